"""The public model contract ``model.rig``: its arrays alone reproduce the forward of both front ends.

A plain linear-blend-skinning written here (SciPy's rotations, a loop over the tree) from nothing but the
rig's fields, at a random pose, gives the model's vertices and output joints; the pose blocks' widths and
offsets are the forward's keywords; the left/right mirror is an involution that swaps named twins."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import smplcore
from smplcore.engine.landmarks import contour_rows
from smplcore.model import PoseBlock, Rig

torch = pytest.importorskip("torch")

MODELS = [
    ("smpl_neutral_pkl", {}),
    ("smpl_male_pkl", {"num_betas": 7}),
    ("smplh_neutral_pkl", {"use_pca": True, "num_pca_comps": 12}),
    ("smplh_female_npz", {"use_pca": False, "flat_hand_mean": True, "num_betas": 16}),
    ("smplx_neutral_npz", {"use_face_contour": True, "num_expression_coeffs": 10}),
    ("smplx_neutral_npz", {"use_pca": False, "age": "kid", "kid": True}),
    ("smplx_male_npz", {"use_pca": True, "num_pca_comps": 6, "use_hands": False}),
    ("mano_right_pkl", {"use_pca": True}),
    ("mano_left_pkl", {"use_pca": False}),
    ("flame_neutral_pkl", {"use_face_contour": True}),
    ("open", {}),
]


def _args(fake_models, key, options):
    options = dict(options)
    if options.pop("kid", False):
        options["kid_template_path"] = str(fake_models["root"] / "smplx" / "smplx_kid_template.npy")
    if key == "open":
        return (None,), {"model_type": "open", **options}
    return (fake_models[key],), options


def _random_params(rig: Rig, batch: int, seed: int) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
    """Forward keywords drawn at random, and from them the (B, 3 J) full pose and the (B, K) coefficients."""
    rng = np.random.default_rng(seed)
    q = rng.normal(0, 0.4, (batch, rig.num_pose))
    params = {b.name: q[:, b.offset : b.offset + b.width] for b in rig.pose_blocks}
    params["betas"] = rng.normal(0, 1, (batch, rig.num_betas))
    coeffs = [params["betas"]]
    if rig.num_expression_coeffs:
        params["expression"] = rng.normal(0, 1, (batch, rig.num_expression_coeffs))
        coeffs.append(params["expression"])
    params["transl"] = rng.normal(0, 0.5, (batch, 3))
    full = np.zeros((batch, 3 * rig.num_joints))
    for b in rig.pose_blocks:  # the PCA bases and the mean pose, from the rig's fields alone
        value = q[:, b.offset : b.offset + b.width]
        full[:, 3 * b.first_joint : 3 * (b.first_joint + b.num_joints)] = (
            value @ rig.hand_components[b.name] if b.pca else value
        )
    full = full + rig.pose_mean
    np.testing.assert_allclose(full, rig.pose_mean + q @ rig.pose_map(), atol=1e-12)
    return params, full, np.concatenate(coeffs, axis=1)


def _plain_lbs(rig: Rig, full_pose: np.ndarray, coeffs: np.ndarray, transl: np.ndarray):
    """(B, V, 3) vertices, (B, J', 3) output joints and (B, J, 3, 3) local rotations, from the rig's fields."""
    batch, J = full_pose.shape[0], rig.num_joints
    dirs = np.concatenate([rig.shapedirs, rig.exprdirs], axis=-1)
    jdirs = np.concatenate([rig.joint_shapedirs, rig.joint_exprdirs], axis=-1)
    rot = Rotation.from_rotvec(full_pose.reshape(-1, 3)).as_matrix().reshape(batch, J, 3, 3)
    verts_out, joints_out = [], []
    for b in range(batch):
        shaped = rig.template + dirs @ coeffs[b]
        joints = rig.template_joints + jdirs @ coeffs[b]
        np.testing.assert_allclose(joints, rig.joint_regressor @ shaped, atol=1e-9)
        features = (rot[b, 1:] - np.eye(3)).reshape(-1)
        posed = shaped + np.einsum("p,pvc->vc", features, rig.posedirs)
        world = np.zeros((J, 4, 4))
        for j in range(J):
            local = np.eye(4)
            local[:3, :3] = rot[b, j]
            parent = rig.parents[j]
            local[:3, 3] = joints[j] - (joints[parent] if parent >= 0 else 0)
            world[j] = local if parent < 0 else world[parent] @ local
        skin = world.copy()
        skin[:, :3, 3] -= np.einsum("jab,jb->ja", world[:, :3, :3], joints)
        blended = np.einsum("vj,jab->vab", rig.weights, skin)
        verts = np.einsum("vab,vb->va", blended[:, :3, :3], posed) + blended[:, :3, 3]
        points = np.concatenate([verts, world[:, :3, 3]])  # the mesh, then the posed skeleton joints
        out = rig.output_rows() @ points
        if rig.contour_faces is not None:
            row = int(contour_rows(rot[b : b + 1], rig.contour_chain)[0])
            corners, w = rig.contour_faces[row], rig.contour_weights[row]
            out[rig.dynamic_output_rows] = np.einsum("lk,lkd->ld", w, verts[corners])
        verts_out.append(verts + transl[b])
        joints_out.append(out + transl[b])
    return np.stack(verts_out), np.stack(joints_out), rot


@pytest.mark.parametrize("key,options", MODELS)
def test_the_rig_alone_reproduces_both_front_ends(fake_models, key, options):
    args, kwargs = _args(fake_models, key, options)
    numpy_model = smplcore.BodyModel(*args, dtype=np.float64, **kwargs)
    torch_model = smplcore.create(*args, dtype=torch.float64, **kwargs)
    rig = numpy_model.rig
    assert isinstance(rig, Rig) and torch_model.rig.num_pose == rig.num_pose
    params, full, coeffs = _random_params(rig, 3, seed=len(key))
    expected_verts, expected_joints, _ = _plain_lbs(rig, full, coeffs, params["transl"])
    # the translation is folded into the skinning, exact when each vertex's weights sum to 1 (float32-stored
    # weights, as the open model's, sum to 1 within ~1e-7: that times |transl|)
    tol = 1e-9 + 2 * np.abs(params["transl"]).max() * np.abs(rig.weights.sum(axis=1) - 1).max()
    out = numpy_model(**params)
    np.testing.assert_allclose(out.full_pose, full, atol=1e-12)
    np.testing.assert_allclose(out.vertices, expected_verts, atol=tol)
    np.testing.assert_allclose(out.joints, expected_joints, atol=tol)
    t_out = torch_model(**{k: torch.as_tensor(v) for k, v in params.items()})
    np.testing.assert_allclose(t_out.vertices.detach().numpy(), expected_verts, atol=tol)
    np.testing.assert_allclose(t_out.joints.detach().numpy(), expected_joints, atol=tol)


@pytest.mark.parametrize("key,options", MODELS)
def test_the_rigs_sizes_and_names_are_the_forwards(fake_models, key, options):
    args, kwargs = _args(fake_models, key, options)
    for model in (smplcore.BodyModel(*args, **kwargs), smplcore.create(*args, **kwargs)):
        rig = model.rig
        assert model.rig is rig  # built once
        out = model() if isinstance(model, smplcore.BodyModel) else model(return_verts=True)
        assert len(rig.output_joint_names) == out.joints.shape[1] == rig.output_rows().shape[0]
        assert list(rig.output_joint_names) == list(model.joint_names)
        assert rig.output_joint_names[: rig.num_joints] == rig.joint_names
        assert (rig.num_vertices, rig.num_betas) == (out.vertices.shape[1], model.num_betas)
        assert rig.num_expression_coeffs == getattr(model, "num_expression_coeffs", 0)
        assert rig.faces.dtype == np.int64 and rig.faces.shape[1] == 3
        assert rig.posedirs.shape == (9 * (rig.num_joints - 1), rig.num_vertices, 3)
        assert rig.shapedirs.shape == (rig.num_vertices, 3, rig.num_betas)
        assert rig.parents[0] == -1 and all(0 <= p < j for j, p in enumerate(rig.parents[1:], 1))
        assert sorted(np.concatenate(rig.levels).tolist()) == list(range(rig.num_joints))


@pytest.mark.parametrize("key,options", MODELS)
def test_pose_blocks_are_the_forward_keywords_with_their_widths_and_offsets(fake_models, key, options):
    args, kwargs = _args(fake_models, key, options)
    model = smplcore.create(*args, **kwargs)
    rig = model.rig
    assert [b.name for b in rig.pose_blocks] == [b.name for b in model.SPEC.pose_blocks]
    offset = joint = 0
    for block in rig.pose_blocks:
        assert isinstance(block, PoseBlock)
        assert (block.offset, block.first_joint) == (offset, joint)
        if not model.LAYER and hasattr(model, block.name):  # the module's parameter has the forward's width
            assert getattr(model, block.name).shape[-1] == block.width
        assert block.width == (rig.hand_components[block.name].shape[0] if block.pca else 3 * block.num_joints)
        assert block.pca == (block.name in rig.hand_components)
        offset, joint = offset + block.width, joint + block.num_joints
    assert (offset, joint) == (rig.num_pose, rig.num_joints)
    assert rig.pose_mean.shape == (3 * rig.num_joints,)
    for name, mean in rig.hand_means.items():
        np.testing.assert_array_equal(rig.pose_mean[rig.block(name).full_pose_columns], mean)


@pytest.mark.parametrize("key,options", MODELS)
def test_the_mirror_is_an_involution_swapping_left_and_right(fake_models, key, options):
    args, kwargs = _args(fake_models, key, options)
    rig = smplcore.BodyModel(*args, **kwargs).rig
    np.testing.assert_array_equal(rig.mirror[rig.mirror], np.arange(rig.num_joints))
    for j, twin in enumerate(rig.mirror):
        name, other = rig.joint_names[j], rig.joint_names[twin]
        if name.startswith("left_"):
            assert other == "right_" + name[5:]
        elif name.startswith("right_"):
            assert other == "left_" + name[6:]
        else:
            assert twin == j
    if rig.model_type in ("smpl", "smplh", "smplx", "open"):
        assert rig.mirror[1] == 2  # left_hip <-> right_hip
        assert (rig.mirror != np.arange(rig.num_joints)).sum() >= 14


def test_the_rig_is_frozen_and_read_only(fake_models):
    rig = smplcore.BodyModel(fake_models["smplx_neutral_npz"]).rig
    with pytest.raises(Exception):
        rig.num_betas = 3  # type: ignore[misc]
    for array in (rig.template, rig.shapedirs, rig.posedirs, rig.weights, rig.hand_components["left_hand_pose"]):
        with pytest.raises(ValueError):
            array[0] = 0
    assert rig.template.dtype == rig.shapedirs.dtype == np.float64
    assert rig.uv is not None and rig.uv.ft.shape == rig.faces.shape


def test_options_are_applied_in_the_rig(fake_models, tmp_path):
    path = fake_models["smplx_neutral_npz"]
    base = smplcore.BodyModel(path).rig
    template = np.asarray(base.template) + 0.01
    rig = smplcore.BodyModel(path, num_betas=5, num_expression_coeffs=3, v_template=template, flat_hand_mean=True).rig
    assert (rig.num_betas, rig.num_expression_coeffs) == (5, 3)
    assert rig.exprdirs.shape[-1] == rig.joint_exprdirs.shape[-1] == 3
    np.testing.assert_allclose(rig.template, template)
    np.testing.assert_allclose(rig.template_joints, rig.joint_regressor @ template)
    assert not rig.pose_mean.any() and base.pose_mean.any()
    mano = smplcore.BodyModel(fake_models["mano_left_pkl"]).rig
    assert (mano.gender, mano.side, mano.model_type) == ("neutral", "left", "mano")


def test_mano_fix_left_shapedirs_reaches_the_rig(fake_models):
    model = smplcore.create(fake_models["mano_left_pkl"], dtype=torch.float64)
    before = model.rig.shapedirs.copy()
    model.fix_left_shapedirs()
    np.testing.assert_array_equal(model.rig.shapedirs[:, 0], -before[:, 0])
    np.testing.assert_array_equal(model.rig.shapedirs, model.shapedirs.numpy())


def test_dmpl_and_regressed_points_are_in_the_rig(tmp_path):
    from fakes_dmpl import write_dmpl

    num_vertices = smplcore.BodyModel(model_type="open").rig.num_vertices
    dmpl = write_dmpl(tmp_path, num_vertices=num_vertices, num_dmpls=4)
    model = smplcore.BodyModel(model_type="open", dtype=np.float64, dmpl_path=dmpl, joint_regressors={"coco17": "open"})
    rig = model.rig
    assert rig.num_dmpls == 4 and rig.dmpldirs.shape == (num_vertices, 3, 4)
    assert rig.joint_dmpldirs.shape == (24, 3, 4) and rig.blend_dirs.shape[-1] == 10 + 4
    k = rig.regressor_weights.shape[0]
    assert k == 17 and rig.output_joint_names[-k:] == tuple(model.joint_names[-k:])
    out = model(body_pose=np.full((1, 69), 0.1), dmpls=np.ones((1, 4)))
    points = np.concatenate([out.vertices[0], out.joints[0, :24]])
    np.testing.assert_allclose(rig.output_rows() @ points, out.joints[0], atol=1e-9)
