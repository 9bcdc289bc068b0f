"""glTF binary export: Khronos validator with 0 errors, and an independent re-evaluation (pygltflib arrays,
NumPy skinning) matching the model's forward pass without pose correctives."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pygltflib", reason="the export extra (pygltflib) is not installed")

import smplcore
from export_helpers import GlbReader, issues, make_motion, open_model, three_js, validate, without_correctives
from smplcore.export import ExportReport, prepare_animation, save_glb, weight_colors

pytestmark = pytest.mark.filterwarnings("ignore:.*pose-corrective.*:UserWarning")


def _forward(model, motion, frame):
    """Vertices and skeleton joints of ``frame`` from the model without pose correctives."""
    plain = without_correctives(model)
    params = motion.model_params(model.model_type, model.skeleton_joint_names)
    one = {k: v[frame : frame + 1] if k not in ("betas",) else v for k, v in params.items()}
    out = plain(**one)
    return out.vertices[0], out.joints[0, : len(model.skeleton_joint_names)]


def _model_vertex_of(reader, model):
    """The model vertex each written vertex copies, read off the index buffer: written face i is model face i
    (a mesh split along its UV seams has more vertices than the model; without a UV map this is the identity)."""
    prim = reader.gltf.meshes[0].primitives[0]
    written = reader.array(prim.indices).reshape(-1, 3)
    ids = np.full(reader.array(prim.attributes.POSITION).shape[0], -1)
    ids[written.ravel()] = np.asarray(model.faces).ravel()
    np.testing.assert_array_equal(ids[written], model.faces)  # every written vertex copies exactly one
    assert ids.min() >= 0
    return ids


def _check_against_model(path, model, motion, frames, vertex_tol, joint_tol=1e-4):
    reader = GlbReader(path)
    ids = _model_vertex_of(reader, model)
    np.testing.assert_allclose(reader.times(), np.arange(motion.num_frames) / motion.fps, atol=1e-5)
    worst = 0.0
    for k in frames:
        verts, joints = _forward(model, motion, k)
        got_joints = reader.joint_positions(k)
        np.testing.assert_allclose(got_joints, joints, atol=joint_tol, rtol=0, err_msg=f"joints, frame {k}")
        err = float(np.linalg.norm(reader.skinned_vertices(k) - verts[ids], axis=-1).max())
        assert err <= vertex_tol, f"frame {k}: vertices off by {err * 1000:.3f} mm (allowed {vertex_tol * 1000:.3f})"
        worst = max(worst, err)
    return worst


@pytest.fixture(scope="module")
def smpl(fake_models):
    return smplcore.BodyModel(fake_models["smpl_neutral_pkl"])


@pytest.fixture(scope="module")
def smpl_glb(tmp_path_factory, smpl):
    motion = make_motion("smpl", seconds=2.0, fps=30.0)
    path = tmp_path_factory.mktemp("glb") / "smpl.glb"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        report = save_glb(path, smpl, motion)
    return path, motion, report, [str(w.message) for w in caught]


def test_validator_reports_no_errors(smpl_glb):
    path, _, _, _ = smpl_glb
    report = validate(path)
    assert report["issues"]["numErrors"] == 0, issues(report)
    assert report["issues"]["numWarnings"] == 0, issues(report, 1)
    info = report["info"]
    assert info["hasSkins"] and info["animationCount"] == 1 and info["maxInfluences"] == 4
    assert info["totalVertexCount"] == 6890


def test_reevaluation_matches_forward_without_correctives(smpl_glb, smpl):
    path, motion, report, _ = smpl_glb
    frames = [0, 1, motion.num_frames // 2, motion.num_frames - 1]
    # The fake has at most 3 weights per vertex: the top-4 skin is exact up to float32.
    worst = _check_against_model(path, smpl, motion, frames, vertex_tol=1e-3)
    assert worst < 1e-5
    assert report.top4_max_error == 0.0 and report.top4_vertices_affected == 0


def test_report_and_structure(smpl_glb, smpl):
    path, motion, report, caught = smpl_glb
    assert isinstance(report, ExportReport)
    assert report.num_frames == motion.num_frames and report.fps == motion.fps
    assert report.file_size == path.stat().st_size
    # The fake SMPL has pose correctives: reported, warned, and measured.
    assert report.pose_corrective_max is not None and report.pose_corrective_max > 0
    assert any("pose-corrective" in w for w in report.warnings) and any("pose-corrective" in w for w in caught)
    reader = GlbReader(path)
    gltf = reader.gltf
    names = smpl.skeleton_joint_names
    assert [gltf.nodes[j].name for j in gltf.skins[0].joints] == names
    rest_verts, rest_joints = smpl.rest_pose(motion.betas[: smpl.num_betas])
    np.testing.assert_allclose(reader.array(gltf.meshes[0].primitives[0].attributes.POSITION), rest_verts, atol=1e-6)
    # Rest transforms: translation joint - parent, no rotation; inverse bind matrices translate(-joint).
    for j, parent in enumerate(smpl.parents):
        node = gltf.nodes[j]
        expected = rest_joints[j] - (rest_joints[parent] if parent >= 0 else 0)
        np.testing.assert_allclose(node.translation, expected, atol=1e-6)
        assert node.rotation is None
    ibm = reader.array(gltf.skins[0].inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)
    np.testing.assert_allclose(ibm[:, :3, 3], -rest_joints, atol=1e-6)
    np.testing.assert_allclose(ibm[:, :3, :3], np.broadcast_to(np.eye(3), ibm[:, :3, :3].shape), atol=0)
    # Quaternions are unit length and sign-continuous over time.
    anim = gltf.animations[0]
    for channel in anim.channels:
        if channel.target.path == "rotation":
            q = reader.array(anim.samplers[channel.sampler].output)
            np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-6)
            assert np.all(np.einsum("ij,ij->i", q[1:], q[:-1]) >= 0)
    weights = reader.array(gltf.meshes[0].primitives[0].attributes.WEIGHTS_0)
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-6)


def test_top4_truncation_error_is_measured(tmp_path, fake_models):
    """Up to 6 influences: the report's max/mean match an independent measurement over every frame."""
    base = smplcore.BodyModel(fake_models["smpl_neutral_pkl"])
    rng = np.random.default_rng(3)
    w = base.skinning_weights.copy()
    spread = np.zeros_like(w)  # up to 3 more joints per vertex (at most 6 influences in all)
    rows = np.repeat(np.arange(len(w)), 3)
    spread[rows, rng.integers(0, w.shape[1], rows.size)] = rng.random(rows.size) * (rng.random(rows.size) < 0.5) * 0.08
    w = (w + spread) / (w + spread).sum(axis=1, keepdims=True)
    model = smplcore.BodyModel(data=base.setup.data.replace(weights=w, posedirs=None))
    assert 4 < (w > 0).sum(axis=1).max() <= 8
    motion = make_motion("smpl", seconds=0.5, fps=30.0, seed=4)
    report = save_glb(tmp_path / "t.glb", model, motion)
    assert report.top4_vertices_affected == int(((w > 0).sum(axis=1) > 4).sum())
    assert report.top4_max_error > 1e-4 and 0 < report.top4_mean_error < report.top4_max_error
    reader = GlbReader(tmp_path / "t.glb")
    errors = []
    for k in range(motion.num_frames):
        verts, _ = _forward(model, motion, k)
        errors.append(np.linalg.norm(reader.skinned_vertices(k) - verts, axis=-1))
    errors = np.array(errors)
    assert errors.max() == pytest.approx(report.top4_max_error, abs=2e-6)
    assert errors.mean() == pytest.approx(report.top4_mean_error, abs=2e-7)
    assert validate(tmp_path / "t.glb")["issues"]["numErrors"] == 0
    # Eight influences carry every weight of these vertices: exact again.
    report8 = save_glb(tmp_path / "t8.glb", model, motion, influences=8)
    assert report8.top4_max_error == 0.0
    _check_against_model(tmp_path / "t8.glb", model, motion, [0, motion.num_frames - 1], vertex_tol=1e-5)
    result = validate(tmp_path / "t8.glb")
    assert result["issues"]["numErrors"] == 0, issues(result)


def test_smplh_amass_motion_with_hands(tmp_path, fake_models):
    model = smplcore.BodyModel(fake_models["smplh_female_npz"], use_pca=False, flat_hand_mean=True, num_betas=16)
    motion = make_motion("smplh", seconds=1.0, fps=60.0, num_betas=16)
    save_glb(tmp_path / "h.glb", model, motion, vertex_colors=weight_colors(model.skinning_weights))
    result = validate(tmp_path / "h.glb")
    assert result["issues"]["numErrors"] == 0, issues(result)
    assert result["info"]["maxAttributes"] == 5  # POSITION NORMAL JOINTS_0 WEIGHTS_0 COLOR_0
    _check_against_model(tmp_path / "h.glb", model, motion, [0, 30, 59], vertex_tol=1e-5)


def test_smplx_expression_morph_targets(tmp_path, fake_models):
    model = smplcore.BodyModel(
        fake_models["smplx_neutral_npz"], use_pca=False, flat_hand_mean=True, num_expression_coeffs=10
    )
    motion = make_motion("smplx", seconds=1.0, fps=30.0, expression=10)
    with pytest.warns(UserWarning, match="needs morph targets"):
        save_glb(tmp_path / "plain.glb", model, motion)
    report = save_glb(tmp_path / "x.glb", model, motion, morph_targets=True)
    assert report.morph_targets == [f"beta_{k}" for k in range(10)] + [f"expr_{k}" for k in range(10)]
    result = validate(tmp_path / "x.glb")
    assert result["issues"]["numErrors"] == 0, issues(result)
    assert result["info"]["hasMorphTargets"]
    reader = GlbReader(tmp_path / "x.glb")
    assert reader.gltf.meshes[0].extras["targetNames"] == report.morph_targets
    # Expression moves the model's rest joints a little (a rig's skeleton is fixed): that much is allowed.
    shift = max(
        (
            float(n.split("up to ")[1].split(" mm")[0]) / 1000
            for n in report.warnings
            if "moves the model's rest joints" in n
        ),
        default=0.0,
    )
    _check_against_model(
        tmp_path / "x.glb", model, motion, [0, 15, 29], vertex_tol=shift + 1e-5, joint_tol=shift + 1e-5
    )
    # Shape targets are edits relative to the baked body: weight w on beta_k adds w * shapedirs[:, :, k].
    prim = reader.gltf.meshes[0].primitives[0]
    target = prim.targets[0]
    delta = reader.array(target["POSITION"] if isinstance(target, dict) else target.POSITION)
    np.testing.assert_allclose(delta, model.setup.shapedirs[_model_vertex_of(reader, model), :, 0], atol=1e-6)


def test_single_parameter_set(tmp_path, smpl):
    rng = np.random.default_rng(5)
    params = {
        "betas": rng.normal(size=10),
        "body_pose": rng.normal(0, 0.3, 69),
        "global_orient": [0.1, 0.5, 0.0],
        "transl": [0.0, 0.2, 1.0],
    }
    report = save_glb(tmp_path / "one.glb", smpl, params)
    assert report.num_frames == 1
    result = validate(tmp_path / "one.glb")
    assert result["issues"]["numErrors"] == 0, issues(result)
    reader = GlbReader(tmp_path / "one.glb")
    out = without_correctives(smpl)(**{k: np.asarray(v)[None] for k, v in params.items()})
    np.testing.assert_allclose(reader.skinned_vertices(0), out.vertices[0], atol=1e-5)
    np.testing.assert_allclose(reader.joint_positions(0), out.joints[0, :24], atol=1e-5)


def test_parameter_batch_and_fps(tmp_path, smpl):
    rng = np.random.default_rng(6)
    frames = 12
    params = {
        "betas": np.zeros((1, 10)),
        "body_pose": rng.normal(0, 0.2, (frames, 69)),
        "global_orient": np.zeros((1, 3)),
        "transl": rng.normal(0, 0.1, (frames, 3)),
    }
    report = save_glb(tmp_path / "b.glb", smpl, params, fps=24)
    assert report.num_frames == frames and report.fps == 24
    reader = GlbReader(tmp_path / "b.glb")
    np.testing.assert_allclose(reader.times(), np.arange(frames) / 24, atol=1e-6)
    out = without_correctives(smpl)(**params)
    np.testing.assert_allclose(reader.skinned_vertices(7), out.vertices[7], atol=1e-5)


def test_rejects_varying_shape(tmp_path, smpl):
    params = {"betas": np.random.default_rng(0).normal(size=(3, 10)), "body_pose": np.zeros((3, 69))}
    with pytest.raises(smplcore.ShapeError, match="one body shape"):
        save_glb(tmp_path / "v.glb", smpl, params)
    with pytest.raises(ValueError, match="influences"):
        save_glb(tmp_path / "v.glb", smpl, {"body_pose": np.zeros(69)}, influences=5)


def test_extra_betas_are_dropped_with_a_warning(tmp_path, smpl):
    motion = make_motion("smpl", seconds=0.2, num_betas=16)
    with pytest.warns(UserWarning, match="betas: the input has 16"):
        anim = prepare_animation(smpl, motion)
    np.testing.assert_array_equal(anim.betas, motion.betas[:10])


def test_open_model(tmp_path):
    model = open_model()
    motion = make_motion("smpl", seconds=2.0, fps=30.0, seed=1)
    report = save_glb(tmp_path / "open.glb", model, motion)
    result = validate(tmp_path / "open.glb")
    assert result["issues"]["numErrors"] == 0, issues(result)
    assert report.pose_corrective_max is None and not report.warnings
    frames = [0, 20, motion.num_frames - 1]
    # The open model keeps at most 4 joints per vertex: its glb skins exactly like the model.
    assert (model.skinning_weights > 0).sum(axis=1).max() <= 4
    assert report.top4_max_error == 0.0 and report.top4_vertices_affected == 0
    worst = _check_against_model(tmp_path / "open.glb", model, motion, frames, vertex_tol=1e-5)
    assert worst <= 1e-3
    # With eight influences every weight is kept: within float32 of the model.
    save_glb(tmp_path / "open8.glb", model, motion, influences=8)
    assert validate(tmp_path / "open8.glb")["issues"]["numErrors"] == 0
    _check_against_model(tmp_path / "open8.glb", model, motion, frames, vertex_tol=1e-5)


def test_three_js_plays_the_animation(tmp_path, smpl_glb, smpl):
    """three.js (GLTFLoader, AnimationMixer, SkinnedMesh.getVertexPosition) shows the model's body."""
    path, motion, _, _ = smpl_glb
    frames = [0, 17, motion.num_frames - 1]
    result = three_js(path, motion.fps, frames)
    clip_seconds = result["duration"]  # the animation's length, as three.js reads it
    assert result["tracks"] == 25
    assert clip_seconds == pytest.approx((motion.num_frames - 1) / motion.fps)
    for k in frames:
        verts, joints = _forward(smpl, motion, k)
        np.testing.assert_allclose(result["bones"][str(k)], joints, atol=1e-4, rtol=0)
        np.testing.assert_allclose(result["vertices"][str(k)], verts, atol=1e-4, rtol=0)


def _blender_python():
    exe = os.environ.get("SMPLCORE_TEST_BLENDER_PYTHON")
    if exe:
        return exe
    if importlib.util.find_spec("bpy") is not None:
        return sys.executable
    pytest.skip(
        "Blender's Python module is not available: set SMPLCORE_TEST_BLENDER_PYTHON to a Python with "
        "`pip install bpy` (a separate virtualenv) to run this check"
    )


def test_blender_imports_glb_and_bvh(tmp_path, smpl):
    """Blender's own glTF and BVH importers (through bpy) reproduce the model. Optional: needs bpy."""
    from smplcore.export import save_bvh

    exe = _blender_python()
    motion = make_motion("smpl", seconds=1.0, fps=30.0, seed=8)
    save_glb(tmp_path / "b.glb", smpl, motion)
    save_bvh(tmp_path / "b.bvh", smpl, motion)
    frames = [0, 11, motion.num_frames - 1]
    result = subprocess.run(
        [
            exe,
            str(Path(__file__).with_name("blender_check.py")),
            str(tmp_path / "b.glb"),
            str(motion.fps),
            ",".join(map(str, frames)),
            str(tmp_path / "b.bvh"),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    data = json.loads(result.stdout.split("\nJSON:", 1)[1])
    assert data["bvh_fps"] == pytest.approx(motion.fps)
    for k in frames:
        verts, joints = _forward(smpl, motion, k)
        np.testing.assert_allclose(data["vertices"][str(k)], verts, atol=1e-4, rtol=0)
        for bones in (data["bones"][str(k)], data["bvh_bones"][str(k)]):
            got = np.array([bones[name] for name in smpl.skeleton_joint_names])
            np.testing.assert_allclose(got, joints, atol=1e-4, rtol=0)
