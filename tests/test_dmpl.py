"""DMPL soft-tissue blend shapes (``dmpl_path=``, forward ``dmpls``): both front ends, the oracle, errors,
smplx's state_dict untouched without them, and ``smplcore process`` / ``smplcore export --dmpl``."""

from __future__ import annotations

import numpy as np
import pytest

import smplcore
from fakes_dmpl import dmpl_eigvec, dmpl_sequence, write_dmpl
from oracle import oracle
from smplcore.errors import ModelFileError

torch = pytest.importorskip("torch")

RNG = np.random.default_rng(7)


@pytest.fixture(scope="module")
def dmpl_file(tmp_path_factory):
    return write_dmpl(tmp_path_factory.mktemp("dmpl"))


def _numpy(fake_models, key, dmpl_file=None, **options):
    options.setdefault("dtype", np.float64)
    if dmpl_file is not None:
        options["dmpl_path"] = dmpl_file
    return smplcore.BodyModel(fake_models[key], **options)


@pytest.mark.parametrize(
    "key, options",
    [
        ("smpl_neutral_pkl", {}),
        ("smplh_female_npz", {"use_pca": False, "flat_hand_mean": True, "num_betas": 16}),
    ],
)
def test_zero_pose_offsets_are_eigvec_times_dmpls(fake_models, dmpl_file, key, options):
    model = _numpy(fake_models, key, dmpl_file, **options)
    assert model.num_dmpls == 8
    dmpls = RNG.normal(size=(3, 8))
    betas = RNG.normal(size=(3, 10))
    offsets = model(betas=betas, dmpls=dmpls).vertices - model(betas=betas).vertices
    np.testing.assert_allclose(offsets, np.einsum("vdk,bk->bvd", dmpl_eigvec(), dmpls), atol=1e-12)
    fewer = model(betas=betas, dmpls=dmpls[:, :3]).vertices - model(betas=betas).vertices  # narrower: zero-padded
    np.testing.assert_allclose(fewer, np.einsum("vdk,bk->bvd", dmpl_eigvec()[:, :, :3], dmpls[:, :3]), atol=1e-12)


def _oracle_with_dmpls(model, params, dmpls, **options):
    """The oracle of tests/oracle.py with the DMPL columns appended to the shape basis (human_body_prior's way:
    one shape blend of [betas, dmpls] before joint regression and posing)."""
    data = model.setup.data
    nb = model.num_betas
    shapedirs = np.concatenate([np.asarray(data.shapedirs)[:, :, :nb], dmpl_eigvec()], axis=2)
    betas = np.zeros((dmpls.shape[0], nb))
    betas[:, : params["betas"].shape[1]] = params["betas"]
    rest = {k: v for k, v in params.items() if k != "betas"}
    return oracle(
        data.replace(shapedirs=shapedirs), {**rest, "betas": np.c_[betas, dmpls]}, num_betas=nb + 8, **options
    )


@pytest.mark.parametrize("kernel", ["auto", "reference"])
def test_posed_body_matches_the_oracle_on_vertices_and_joints(fake_models, dmpl_file, kernel):
    opts = {"use_pca": False, "flat_hand_mean": False, "num_betas": 16}
    model = _numpy(fake_models, "smplh_female_npz", dmpl_file, kernel=kernel, **opts)
    batch = 4
    params = {
        "betas": RNG.normal(size=(batch, 16)),
        "global_orient": RNG.normal(scale=0.5, size=(batch, 3)),
        "body_pose": RNG.normal(scale=0.4, size=(batch, 63)),
        "left_hand_pose": RNG.normal(scale=0.3, size=(batch, 45)),
        "right_hand_pose": RNG.normal(scale=0.3, size=(batch, 45)),
        "transl": RNG.normal(size=(batch, 3)),
    }
    dmpls = RNG.normal(size=(batch, 8))
    out = model(dmpls=dmpls, **params)
    verts, joints = _oracle_with_dmpls(model, params, dmpls, use_pca=False, flat_hand_mean=False)
    np.testing.assert_allclose(out.vertices, verts, atol=1e-10)
    np.testing.assert_allclose(out.joints, joints, atol=1e-10)
    # soft tissue moves the posed body (and, through the regressor, its joints), as in human_body_prior
    plain = model(**params)
    assert np.abs(out.vertices - plain.vertices).max() > 5e-3


def test_torch_equals_numpy_with_gradients(fake_models, dmpl_file):
    path = fake_models["smplh_female_npz"]
    opts = {"use_pca": False, "num_betas": 16}
    numpy_model = smplcore.BodyModel(path, dmpl_path=dmpl_file, dtype=np.float64, **opts)
    module = smplcore.create(path, model_type="smplh", dmpl_path=dmpl_file, dtype=torch.float64, **opts)
    assert module.num_dmpls == 8
    dmpls = RNG.normal(size=(2, 8))
    pose = RNG.normal(scale=0.3, size=(2, 63))
    expected = numpy_model(dmpls=dmpls, body_pose=pose)
    dm = torch.tensor(dmpls, requires_grad=True)
    out = module(dmpls=dm, body_pose=torch.tensor(pose))
    np.testing.assert_allclose(out.vertices.detach().numpy(), expected.vertices, atol=1e-10)
    np.testing.assert_allclose(out.joints.detach().numpy(), expected.joints, atol=1e-10)
    out.vertices.sum().backward()
    # d(sum of vertices)/d dmpls_k: the k-th blend shape's sum, rotated by the skinning: compare by finite differences
    eps = 1e-6
    bumped = dmpls.copy()
    bumped[0, 2] += eps
    numeric = (numpy_model(dmpls=bumped, body_pose=pose).vertices.sum() - expected.vertices.sum()) / eps
    assert dm.grad[0, 2].item() == pytest.approx(numeric, rel=1e-4, abs=1e-6)


def test_smplx_expression_and_dmpl_columns_stay_apart(fake_models, tmp_path):
    """Any model whose vertex count matches takes a DMPL file; the coefficients are betas, expression, dmpls."""
    model_file = fake_models["smplx_neutral_npz"]
    num_vertices = smplcore.BodyModel(model_file).setup.data.num_vertices
    path = write_dmpl(tmp_path, num_vertices=num_vertices, num_dmpls=4)
    model = smplcore.BodyModel(model_file, dmpl_path=path, dtype=np.float64, flat_hand_mean=True)
    expression, dmpls = RNG.normal(size=(1, 10)), RNG.normal(size=(1, 4))
    both = model(expression=expression, dmpls=dmpls).vertices
    np.testing.assert_allclose(
        both - model(expression=expression).vertices,
        np.einsum("vdk,bk->bvd", dmpl_eigvec(num_vertices, 4), dmpls),
        atol=1e-12,
    )


def test_state_dict_is_smplx_s_without_a_dmpl_file(fake_models, dmpl_file):
    path = fake_models["smplh_female_npz"]
    plain = smplcore.create(path, model_type="smplh", use_pca=False)
    with_dmpl = smplcore.create(path, model_type="smplh", use_pca=False, dmpl_path=dmpl_file)
    assert "dmpldirs" not in dict(plain.named_buffers()) and plain.num_dmpls == 0
    assert set(with_dmpl.state_dict()) - set(plain.state_dict()) == {"dmpldirs"}
    assert tuple(with_dmpl.dmpldirs.shape) == (6890, 3, 8)


def test_dmpls_without_a_dmpl_file_is_a_clear_error(fake_models):
    path = fake_models["smpl_neutral_pkl"]
    for call in (
        lambda: smplcore.BodyModel(path)(dmpls=np.zeros((1, 8))),
        lambda: smplcore.create(path)(dmpls=torch.zeros(1, 8)),
    ):
        with pytest.raises(ValueError, match=r"dmpls: this model has no DMPL blend shapes; create it with dmpl_path="):
            call()


def test_bad_dmpl_files_name_the_file_and_key(fake_models, tmp_path):
    path = fake_models["smpl_neutral_pkl"]
    wrong = write_dmpl(tmp_path, num_vertices=778, name="wrong.npz")
    with pytest.raises(ModelFileError, match=r"wrong\.npz \[key 'eigvec'\]: expected shape \(6890, 3, n\)") as info:
        smplcore.BodyModel(path, dmpl_path=wrong)
    assert info.value.key == "eigvec" and info.value.path == str(wrong)
    missing_key = write_dmpl(tmp_path, name="other.npz", key="dirs")
    with pytest.raises(ModelFileError, match=r"other\.npz \[key 'eigvec'\]: missing key; the file has \['dirs'\]"):
        smplcore.create(path, dmpl_path=missing_key)
    with pytest.raises(ModelFileError, match="no such file"):
        smplcore.BodyModel(path, dmpl_path=tmp_path / "absent.npz")
    flat = tmp_path / "flat.npz"
    np.savez(flat, eigvec=np.zeros((6890, 24)))
    with pytest.raises(ModelFileError, match=r"expected shape \(V, 3, n\) DMPL blend shapes, found \(6890, 24\)"):
        smplcore.BodyModel(path, dmpl_path=flat)


def test_process_uses_each_sequence_s_dmpls(fake_models, dmpl_file, tmp_path):
    from smplcore.motion import ProcessOptions, load_motion, process_tree
    from smplcore.motion.synthetic import write_sequence

    seq = write_sequence(tmp_path / "in" / "a_poses.npz", frames=30, fps=30.0, gender="female")
    motion = load_motion(seq)
    assert motion.dmpls is not None and motion.dmpls.shape == (30, 8)
    model_file = fake_models["smplh_female_npz"]
    outputs = {}
    for name, dmpl in (("with", dmpl_file), ("without", None)):
        options = ProcessOptions(model_path=model_file, vertices=True, backend="numpy", dmpl_path=dmpl)
        summary = process_tree(tmp_path / "in", tmp_path / name, options, workers=0, progress=False)
        assert summary.exit_code == 0 and summary.done == 1
        with np.load(tmp_path / name / "a_poses.npz") as f:
            outputs[name] = {k: f[k] for k in ("joints", "vertices")}
    model = smplcore.BodyModel(model_file, dmpl_path=dmpl_file, use_pca=False, flat_hand_mean=True, num_betas=16)
    params = motion.model_params("smplh", model.skeleton_joint_names)
    expected = model(dmpls=motion.dmpls, **params)
    np.testing.assert_allclose(outputs["with"]["vertices"], expected.vertices, atol=1e-5)
    np.testing.assert_allclose(outputs["with"]["joints"], expected.joints[:, :52], atol=1e-5)
    assert np.abs(outputs["with"]["vertices"] - outputs["without"]["vertices"]).max() > 1e-3
    # the skeleton-only path (no vertices) includes the soft tissue's joint shift too
    options = ProcessOptions(model_path=model_file, backend="numpy", dmpl_path=dmpl_file)
    process_tree(tmp_path / "in", tmp_path / "skeleton", options, workers=0, progress=False)
    with np.load(tmp_path / "skeleton" / "a_poses.npz") as f:
        np.testing.assert_allclose(f["joints"], expected.joints[:, :52], atol=1e-5)


def test_process_cli_dmpl_option(fake_models, dmpl_file, tmp_path, capsys):
    from smplcore.cli import main
    from smplcore.motion.synthetic import write_sequence

    write_sequence(tmp_path / "in" / "a_poses.npz", frames=10, fps=30.0, gender="female")
    model_file = str(fake_models["smplh_female_npz"])
    args = ["process", str(tmp_path / "in"), str(tmp_path / "out"), "--model-path", model_file, "--quiet"]
    assert main([*args, "--dmpl", str(dmpl_file), "--workers", "0"]) == 0
    manifest = (tmp_path / "out" / "manifest.json").read_text()
    assert str(dmpl_file.resolve()) in manifest  # a setting of the outputs: a rerun without it is refused
    assert main([*args, "--dmpl", str(tmp_path / "absent.npz"), "--workers", "0"]) == 2
    assert "no such DMPL file" in capsys.readouterr().err


def _dmpl_motion(frames: int = 12):
    from export_helpers import make_motion

    motion = make_motion("smplh", seconds=frames / 30.0, fps=30.0, num_betas=16)
    from dataclasses import replace

    return replace(motion, gender="female", dmpls=dmpl_sequence(motion.num_frames))


def test_export_obj_bakes_the_frame_s_dmpls(fake_models, dmpl_file, tmp_path):
    pytest.importorskip("trimesh")
    from smplcore.cli import main
    from smplcore.motion import save_motion

    motion = _dmpl_motion()
    path = save_motion(motion, tmp_path / "walk.npz")
    model_file = fake_models["smplh_female_npz"]
    out = tmp_path / "frame5.obj"
    args = ["export", str(path), "-o", str(out), "--model-path", str(model_file), "--frame", "5"]
    assert main([*args, "--dmpl", str(dmpl_file)]) == 0
    model = smplcore.BodyModel(model_file, dmpl_path=dmpl_file, use_pca=False, flat_hand_mean=True, num_betas=16)
    params = motion.model_params("smplh", model.skeleton_joint_names)
    expected = model(dmpls=motion.dmpls[5:6], **{k: v[5:6] if k != "betas" else v for k, v in params.items()})
    lines = [line.split()[1:] for line in out.read_text().splitlines() if line.startswith("v ")]
    np.testing.assert_allclose(np.asarray(lines, float), expected.vertices[0], atol=1e-5)


def test_export_glb_animates_dmpl_morph_targets(fake_models, dmpl_file, tmp_path, capsys):
    pytest.importorskip("pygltflib")
    from export_helpers import GlbReader, validate
    from smplcore.cli import main
    from smplcore.motion import save_motion

    motion = _dmpl_motion()
    path = save_motion(motion, tmp_path / "walk.npz")
    model_file = fake_models["smplh_female_npz"]
    out = tmp_path / "walk.glb"
    assert main(["export", str(path), "-o", str(out), "--model-path", str(model_file), "--dmpl", str(dmpl_file)]) == 0
    assert validate(out)["issues"]["numErrors"] == 0
    reader = GlbReader(out)
    assert reader.gltf.meshes[0].extras["targetNames"] == [f"dmpl_{k}" for k in range(8)]
    np.testing.assert_allclose(reader.morph_weights(7), motion.dmpls[7], atol=1e-6)
    model = smplcore.BodyModel(model_file, dmpl_path=dmpl_file, use_pca=False, flat_hand_mean=True, num_betas=16)
    # the rig: soft tissue on the rest mesh (morph targets), the skeleton of the body without it, full-weight LBS
    # (the fake's vertices have at most 3 weights: the top 4 lose nothing), no pose correctives
    from smplcore.engine import reference

    betas = np.asarray(motion.betas)[None]
    dirs = np.asarray(model.setup.shapedirs, np.float64)
    template = np.asarray(model.setup.data.v_template, np.float64)
    rest = reference.shape_blend(template, np.concatenate([dirs, dmpl_eigvec()], 2), np.c_[betas, motion.dmpls[7:8]])
    joints = reference.regress_joints(model.setup.data.J_regressor, reference.shape_blend(template, dirs, betas))
    _, relative = reference.kinematic_chain(
        model(**_frame(motion, model, 7), dmpls=motion.dmpls[7:8]).rotmats, joints, model.parents
    )
    expected = reference.linear_blend_skinning(rest, relative, model.skinning_weights)[0]
    expected += motion.trans[7]
    got = reader.skinned_vertices(7)
    np.testing.assert_allclose(got, expected, atol=2e-5)
    assert any("dmpls move the model's joints" in w for w in _report_warnings(capsys))


def _frame(motion, model, k):
    params = motion.model_params("smplh", model.skeleton_joint_names)
    return {name: v[k : k + 1] if name != "betas" else v for name, v in params.items() if name != "transl"}


def _report_warnings(capsys):
    return [line for line in capsys.readouterr().out.splitlines() if line.startswith("warning:")]


@pytest.mark.parametrize("skeleton_only", [False, True])
def test_motion_evaluator_torch_backend_agrees(fake_models, dmpl_file, tmp_path, skeleton_only):
    from smplcore.motion import Evaluator, ModelCache, load_motion
    from smplcore.motion.synthetic import write_sequence

    motion = load_motion(write_sequence(tmp_path / "a_poses.npz", frames=20, fps=30.0, gender="female"))
    model_file = fake_models["smplh_female_npz"]
    out = {}
    for backend in ("numpy", "torch"):
        loaded = ModelCache(model_file, backend=backend, dmpl_path=dmpl_file).get("smplh", "female")
        out[backend] = Evaluator().run(motion, loaded, vertices=not skeleton_only, skeleton_only=skeleton_only)
    np.testing.assert_allclose(out["torch"][0], out["numpy"][0], atol=1e-5)
    plain = ModelCache(model_file, backend="numpy").get("smplh", "female")
    without = Evaluator().run(motion, plain, vertices=not skeleton_only, skeleton_only=skeleton_only)[0]
    assert np.abs(out["numpy"][0] - without).max() > 1e-4  # the soft tissue moves the joints
    if not skeleton_only:
        np.testing.assert_allclose(out["torch"][1], out["numpy"][1], atol=1e-5)
