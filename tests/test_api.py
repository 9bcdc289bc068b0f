"""The torch API's behaviour, including every documented difference from smplx (README)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import pytest

torch = pytest.importorskip("torch")
smplx = pytest.importorskip("smplx")

import smplcore  # noqa: E402
from smplcore.errors import ModelFileError, ShapeError  # noqa: E402
from smplcore.lbs import batch_rodrigues  # noqa: E402

SRC = Path(__file__).resolve().parents[1] / "src"


def _quiet_smplx(*args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return smplx.create(*args, **kwargs)


@pytest.fixture(scope="module")
def smplx_model(fake_models):
    return smplcore.create(fake_models["root"], model_type="smplx", ext="npz")


# -- Differences from smplx --------------------------------------------------------------------------


def test_smpl_honours_ext(fake_models, tmp_path):
    """smplx reads SMPL_*.pkl whatever ``ext`` says; we read the file asked for."""
    shutil.copy(fake_models["smpl_neutral_npz"], tmp_path / "SMPL_NEUTRAL.npz")
    model = smplcore.create(tmp_path, model_type="smpl", ext="npz")
    assert model.setup.data.source.endswith("SMPL_NEUTRAL.npz")
    with pytest.raises(Exception):
        _quiet_smplx(str(tmp_path), model_type="smpl", ext="npz")  # smplx looks for the .pkl


def test_num_betas_is_not_capped_at_10(fake_models):
    """A 16-component SMPL+H file gives 16 betas (smplx silently keeps 10)."""
    model = smplcore.create(fake_models["smplh_female_npz"], use_pca=False, num_betas=16)
    assert model.num_betas == 16
    assert (
        _quiet_smplx(
            str(fake_models["root"]), model_type="smplh", gender="female", ext="npz", use_pca=False, num_betas=16
        ).num_betas
        == 10
    )
    betas = torch.zeros(1, 16)
    betas[0, 12] = 2.0
    with torch.no_grad():
        moved = (model(betas=betas).vertices - model().vertices).abs().max()
    assert moved > 1e-3


def test_expression_broadcasts_over_the_batch(smplx_model):
    pose = torch.randn(4, 63) * 0.2
    expression = torch.randn(1, 10)
    with torch.no_grad():
        a = smplx_model(body_pose=pose, expression=expression)
        b = smplx_model(body_pose=pose, expression=expression.expand(4, -1))
    assert a.vertices.shape[0] == 4
    assert torch.equal(a.vertices, b.vertices)


@pytest.mark.parametrize(
    "model_type,blocks",
    [
        ("smplh", {"global_orient": 1, "body_pose": 21, "left_hand_pose": 15, "right_hand_pose": 15}),
        (
            "smplx",
            {
                "global_orient": 1,
                "body_pose": 21,
                "jaw_pose": 1,
                "leye_pose": 1,
                "reye_pose": 1,
                "left_hand_pose": 15,
                "right_hand_pose": 15,
            },
        ),
    ],
)
def test_pose2rot_false_works_for_smplh_and_smplx(fake_models, model_type, blocks):
    """Rotation matrices through the non-Layer classes equal the Layer classes (smplx raises)."""
    root = fake_models["root"]
    options = {"ext": "npz" if model_type == "smplx" else "pkl"}
    torch.manual_seed(0)
    mats = {k: batch_rodrigues(torch.randn(2 * n, 3) * 0.4).reshape(2, n, 3, 3) for k, n in blocks.items()}
    model = smplcore.create(root, model_type=model_type, **options)
    layer = smplcore.build_layer(root, model_type=model_type, **options)
    reference = smplx.build_layer(str(root), model_type=model_type, **options)
    with torch.no_grad():
        got = model(pose2rot=False, **mats)
        same = layer(**mats)
        expected = reference(**mats)
    assert torch.allclose(got.vertices, same.vertices, atol=1e-6)
    assert (got.vertices - expected.vertices).abs().max() < 1e-5
    with pytest.raises(Exception):
        smplx_model = _quiet_smplx(str(root), model_type=model_type, **options)
        smplx_model(pose2rot=False, **{k: v.reshape(2, -1) for k, v in mats.items()})


def test_no_batch_size_trap(fake_models):
    """Parameters left at their defaults broadcast to the call's batch, whatever ``batch_size`` was."""
    root = fake_models["root"]
    model = smplcore.create(root, model_type="smplx", ext="npz", batch_size=4)
    pose = torch.randn(7, 63) * 0.2
    with torch.no_grad():
        out = model(body_pose=pose)  # betas, hands, face, transl: defaults of batch 4
    assert out.vertices.shape[:2] == (7, 10475)
    with pytest.raises(Exception):
        _quiet_smplx(str(root), model_type="smplx", ext="npz", batch_size=4)(body_pose=pose)
    with torch.no_grad():
        model.betas[1, 0] = 1.0  # the defaults now differ per row: joining batch 7 would be a guess
    with pytest.raises(ShapeError, match="betas: the module's parameter has batch size 4"):
        model(body_pose=pose)


def test_unknown_keywords_warn_once_by_name(fake_models):
    root = fake_models["root"]
    with pytest.warns(UserWarning, match="ignoring unknown keyword argument 'use_magic'"):
        model = smplcore.create(root, model_type="smpl", use_magic=True)
    with pytest.warns(UserWarning, match="'get_skin'"):
        model(get_skin=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model(get_skin=True)  # once per name


# -- Everything else as smplx -------------------------------------------------------------------------


def test_a_v_template_given_to_forward_is_used(fake_models):
    """smplx's forward swallows ``v_template`` (its **kwargs); ours uses it for that call."""
    root = fake_models["root"]
    ref, ours = _quiet_smplx(str(root), model_type="smpl"), smplcore.create(root, model_type="smpl")
    moved = ref.v_template + torch.tensor([0.0, 0.2, 0.0])
    with torch.no_grad(), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert torch.equal(ref(v_template=moved).vertices, ref().vertices)  # ignored
    with torch.no_grad():
        shift = ours(v_template=moved).vertices - ours().vertices
    torch.testing.assert_close(shift, torch.tensor([0.0, 0.2, 0.0]).expand_as(shift), atol=1e-5, rtol=0)


def test_get_num_verts_with_one_template_per_body(fake_models):
    """smplx answers the batch size for a (B, V, 3) ``v_template``; ours the vertices."""
    root = fake_models["root"]
    templates = _quiet_smplx(str(root), model_type="smpl").v_template.expand(4, -1, -1)
    ref = _quiet_smplx(str(root), model_type="smpl", v_template=templates, batch_size=4)
    ours = smplcore.create(root, model_type="smpl", v_template=templates, batch_size=4)
    assert (ref.get_num_verts(), ours.get_num_verts()) == (4, 6890)


def test_narrow_betas_and_expressions_are_zero_padded(smplx_model):
    betas = torch.randn(2, 4)
    expression = torch.randn(2, 3)
    padded = torch.cat([betas, torch.zeros(2, 6)], 1), torch.cat([expression, torch.zeros(2, 7)], 1)
    with torch.no_grad():
        a = smplx_model(betas=betas, expression=expression)
        b = smplx_model(betas=padded[0], expression=padded[1])
    assert torch.equal(a.vertices, b.vertices)


def test_more_betas_than_the_file_holds_warns_and_uses_what_it_holds(fake_models):
    with pytest.warns(UserWarning, match="num_betas=300 asked.*holds 10"):
        model = smplcore.create(fake_models["smpl_male_pkl"], num_betas=300)
    assert model.num_betas == 10 and model.betas.shape == (1, 10)


def test_wrong_shapes_name_the_argument(smplx_model):
    with pytest.raises(ShapeError, match=r"betas: expected shape \(B, <=10\), got \(1, 11\)"):
        smplx_model(betas=torch.zeros(1, 11))
    with pytest.raises(ShapeError, match=r"body_pose: expected shape \(B, 63\) or \(B, 21, 3\), got \(2, 69\)"):
        smplx_model(body_pose=torch.zeros(2, 69))
    with pytest.raises(ShapeError, match="body_pose: batch size 2 does not match the batch size 3"):
        smplx_model(body_pose=torch.zeros(2, 63), global_orient=torch.zeros(3, 3))


def test_pca_without_components_is_a_clear_error(fake_models, monkeypatch):
    from smplcore.frontend import setup

    monkeypatch.setattr(setup, "_warned", set())  # the warning comes once per process: whatever ran before
    path = fake_models["official_smplh_amass_neutral_npz"]
    with pytest.raises(ModelFileError, match="use_pca=True needs.*pass use_pca=False"):
        smplcore.create(path, use_pca=True)
    with pytest.warns(UserWarning, match="no mean hand pose"):
        model = smplcore.create(path, use_pca=False)
    assert model.num_betas == 10 and model.left_hand_pose.shape == (1, 45)


def test_an_amass_smplh_npz_is_read_with_axis_angle_hands_by_default(fake_models):
    """AMASS's SMPL+H .npz has neither hand PCA nor a mean hand pose: without use_pca / flat_hand_mean,
    create() and BodyModel take the hands as axis-angle with a flat mean (as smplcore demo does), silently."""
    path = fake_models["official_smplh_amass_neutral_npz"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model = smplcore.create(path)
        body = smplcore.BodyModel(path)
    assert model.use_pca is False and model.flat_hand_mean is True and model.left_hand_pose.shape == (1, 45)
    assert body.setup.use_pca is False and body.setup.flat_hand_mean is True
    hands = {"left_hand_pose": torch.full((1, 45), 0.1), "right_hand_pose": torch.zeros(1, 45)}
    explicit = smplcore.create(path, use_pca=False, flat_hand_mean=True)
    torch.testing.assert_close(model(**hands).vertices, explicit(**hands).vertices)
    with_pca = smplcore.create(fake_models["root"], model_type="smplh", gender="female", ext="npz")
    assert with_pca.use_pca is True  # a file with hand PCA keeps smplx's default


def test_dtype_and_device_moves(fake_models):
    model = smplcore.create(fake_models["root"], model_type="mano").to(torch.float64)
    out = model(global_orient=torch.zeros(2, 3, dtype=torch.float64))
    assert out.vertices.dtype == torch.float64 and out.vertices.shape == (2, 778, 3)
    assert model.faces_tensor.dtype == torch.long and model.faces.shape == (1538, 3)


def test_outputs_behave_like_smplx_outputs(smplx_model):
    out = smplx_model(return_full_pose=True)
    assert set(out.keys()) >= {"vertices", "joints", "full_pose", "betas", "expression", "jaw_pose", "v_shaped"}
    assert out["vertices"] is out.vertices and out.full_pose.shape == (1, 165)
    shape = smplx_model.forward_shape(betas=torch.ones(1, 10))
    assert torch.allclose(shape.vertices, shape.v_shaped)


def test_joints_only_path_equals_the_full_forward(fake_models):
    model = smplcore.create(fake_models["root"], model_type="smplx", ext="npz", use_face_contour=True)
    torch.manual_seed(1)
    params = {
        "body_pose": torch.randn(3, 63) * 0.3,
        "global_orient": torch.randn(3, 3) * 0.5,
        "betas": torch.randn(3, 10),
        "expression": torch.randn(3, 10),
        "jaw_pose": torch.randn(3, 3) * 0.2,
    }
    with torch.no_grad():
        full = model(**params)
        fast = model(return_verts=False, **params)
    assert fast.vertices is None and fast.joints.shape == (3, 144, 3)
    assert (full.joints - fast.joints).abs().max() < 1e-5


def test_joint_mapper_is_applied_before_translation(fake_models):
    class Mapper(torch.nn.Module):
        def forward(self, joints):
            return joints[:, [0, 15]]

    model = smplcore.create(fake_models["root"], model_type="smpl", joint_mapper=Mapper())
    out = model(transl=torch.ones(1, 3))
    assert out.joints.shape == (1, 2, 3)
    assert torch.allclose(out.joints[0, 0] - 1, model(transl=torch.zeros(1, 3)).joints[0, 0], atol=1e-6)


def test_extra_joint_switches(fake_models):
    root = fake_models["root"]
    assert smplcore.create(root, model_type="smpl", use_hands=False)().joints.shape[1] == 35
    assert smplcore.create(root, model_type="smpl", use_feet_keypoints=False)().joints.shape[1] == 39
    model = smplcore.create(root, model_type="smpl", vertex_ids=dict(smplcore.vertex_ids.vertex_ids["smplh"], nose=7))
    assert torch.equal(model().joints[0, 24], model().vertices[0, 7])


def test_left_mano_shapedirs_fix_is_opt_in(fake_models):
    root = fake_models["root"]
    left = smplcore.create(root, model_type="mano", is_rhand=False)
    fixed = smplcore.create(root, model_type="mano", is_rhand=False, fix_left_shapedirs=True)
    assert torch.equal(fixed.shapedirs[:, 0], -left.shapedirs[:, 0])
    assert torch.equal(fixed.shapedirs[:, 1:], left.shapedirs[:, 1:])
    betas = torch.zeros(1, 10)
    betas[0, 0] = 3.0
    with torch.no_grad():
        a, b = left(betas=betas).vertices, fixed(betas=betas).vertices
    assert not torch.allclose(a, b)


@pytest.mark.parametrize(
    "key,cls",
    [
        ("official_smpl_f_v1_0_pkl", "SMPL"),
        ("official_smplh_amass_neutral_npz", "SMPLH"),
        ("mano_left_pkl", "MANO"),
        ("smplx_male_npz", "SMPLX"),
    ],
)
def test_create_takes_the_model_type_from_the_file(fake_models, key, cls):
    options = {"use_pca": False} if cls == "SMPLH" else {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = smplcore.create(fake_models[key], **options)
    assert type(model).__name__ == cls


def test_flame_from_generic_model_pkl_with_embeddings_beside_it(fake_models, tmp_path):
    for key in ("official_flame_generic_pkl", "flame_static_embedding", "flame_dynamic_embedding"):
        shutil.copy(fake_models[key], tmp_path)
    model = smplcore.create(tmp_path / "generic_model.pkl", use_face_contour=True)
    assert type(model).__name__ == "FLAME" and model().joints.shape == (1, 73, 3)
    (tmp_path / "flame_static_embedding.pkl").unlink()
    with pytest.raises(ModelFileError, match="flame_static_embedding.pkl"):
        smplcore.create(tmp_path / "generic_model.pkl")


def test_numpy_front_end_runs_without_torch(fake_models):
    script = textwrap.dedent(f"""
        import sys
        sys.modules["torch"] = None
        import numpy as np, smplcore
        model = smplcore.BodyModel({str(fake_models["smpl_neutral_pkl"])!r})
        out = model(body_pose=np.zeros((2, 69)))
        print(out.vertices.shape, out.joints.shape)
    """)
    env = dict(os.environ, PYTHONPATH=str(SRC))
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "(2, 6890, 3) (2, 45, 3)"


def test_gradients_flow_to_parameters(fake_models):
    model = smplcore.create(fake_models["root"], model_type="smpl")
    model(body_pose=torch.full((1, 69), 0.1)).joints.sum().backward()
    assert model.betas.grad is not None and torch.isfinite(model.betas.grad).all()
    assert model.global_orient.grad.abs().sum() > 0


def test_v_shaped_is_the_shape_blend_only_and_absent_without_vertices(smplx_model):
    betas, expression = torch.randn(2, 10), torch.randn(2, 10)
    with torch.no_grad():
        out = smplx_model(betas=betas, expression=expression)
        expected = smplx_model.v_template + torch.einsum("bk,vdk->bvd", betas, smplx_model.shapedirs)
        assert (out.v_shaped - expected).abs().max() < 1e-6
        assert smplx_model(betas=betas, return_verts=False).v_shaped is None


def test_v_shaped_is_built_on_first_read_from_the_betas_of_the_call(smplx_model):
    betas = torch.randn(2, 10)
    expected = smplx_model.v_template + torch.einsum("bk,vdk->bvd", betas, smplx_model.shapedirs)
    with torch.no_grad():
        out = smplx_model(betas=betas)
    betas.zero_()  # an in-place edit after the call does not leak into the deferred field
    assert (out.v_shaped - expected).abs().max() < 1e-6
    assert out.v_shaped is out["v_shaped"]  # computed once, then stored
    assert (dict(out.items())["v_shaped"] - expected).abs().max() < 1e-6

    trainable = torch.randn(1, 10, requires_grad=True)
    smplx_model(betas=trainable).v_shaped.sum().backward()
    assert trainable.grad is not None and trainable.grad.abs().sum() > 0
    with torch.no_grad():
        out = smplx_model(betas=trainable)
    assert not out.v_shaped.requires_grad  # read outside no_grad, built as the call was: without a graph
    with torch.inference_mode():
        out = smplx_model(betas=betas)
    assert out.v_shaped.is_inference()


@pytest.mark.parametrize("batch", [1, 100])
def test_a_first_call_in_inference_mode_leaves_the_model_usable_with_autograd(batch):
    """Constants cached during the first call (index tensors, vertex blocks, keypoint subsets) are
    built outside inference mode, so a later call that records gradients can use them."""
    model = smplcore.create(model_type="open")
    gen = torch.Generator().manual_seed(1)
    params = {"betas": torch.randn(batch, 10, generator=gen), "body_pose": 0.3 * torch.randn(batch, 69, generator=gen)}
    with torch.inference_mode():
        first = model(**params)
        joints_only = model(**params, return_verts=False)
    assert first.vertices.is_inference()
    betas = params["betas"].clone().requires_grad_(True)
    out = model(betas=betas, body_pose=params["body_pose"])
    (out.vertices.sum() + out.joints.sum()).backward()
    assert betas.grad is not None and betas.grad.abs().sum() > 0
    assert (out.vertices - first.vertices).abs().max() < 1e-5
    assert (out.joints - joints_only.joints).abs().max() < 1e-5
