"""Engine-ready glTF (``save_glb(..., engine="unreal"|"unity")``): a root bone, a unit scale, feet on the ground,
4 normalised influences, morph weights every frame -- validator clean, re-evaluated with pygltflib + NumPy and
played by three.js; the default export stays the exact one."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

pytest.importorskip("pygltflib", reason="the export extra (pygltflib) is not installed")

from export_helpers import GlbReader, issues, make_motion, open_model, three_js, validate, without_correctives
from smplcore.export import save_glb

pytestmark = pytest.mark.filterwarnings("ignore:.*pose-corrective.*:UserWarning", "ignore:.*another shape space.*")


@pytest.fixture(scope="module")
def unreal(tmp_path_factory):
    model = open_model(num_betas=10)
    motion = make_motion("smpl", seconds=1.0)
    path = tmp_path_factory.mktemp("engine") / "unreal.glb"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        report = save_glb(path, model, motion, engine="unreal", morph_targets=True)
    return model, motion, path, report


def _expected(model, motion, frame):
    plain = without_correctives(model)
    params = motion.model_params("open", model.skeleton_joint_names)
    out = plain(**{n: v[frame : frame + 1] if n != "betas" else v for n, v in params.items()})
    return out.vertices[0], out.joints[0, :24]


def test_validator_clean_and_root_bone(unreal):
    model, motion, path, report = unreal
    result = validate(path)
    assert result["issues"]["numErrors"] == 0, issues(result)
    assert result["issues"]["numWarnings"] == 0, issues(result, 1)
    assert result["info"]["maxInfluences"] == 4
    gltf = GlbReader(path).gltf
    skin = gltf.skins[0]
    root = gltf.nodes[skin.joints[0]]
    assert root.name == "root" and root.translation is None and root.rotation is None and root.children == [0]
    assert skin.skeleton == skin.joints[0] and gltf.scenes[0].nodes[0] == skin.joints[0]
    assert [gltf.nodes[j].name for j in skin.joints[1:]] == list(model.skeleton_joint_names)
    assert report.engine == "unreal" and report.unit_scale == 100.0 and "engine: unreal" in report.summary()


def test_centimetres_feet_on_the_ground_and_the_same_motion(unreal):
    model, motion, path, report = unreal
    reader = GlbReader(path)
    lift = report.ground_lift
    assert lift is not None and lift > 0.5  # the open model's rest pelvis is at the origin
    prim = reader.gltf.meshes[0].primitives[0]
    weights = reader.array(prim.attributes.WEIGHTS_0)
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-6)
    ids = np.full(len(weights), -1)
    ids[reader.array(prim.indices).ravel()] = np.asarray(model.faces).ravel()
    lowest = np.inf
    for k in range(motion.num_frames):
        got = reader.skinned_vertices(k)
        lowest = min(lowest, got[:, 1].min())
        if k % 7 == 0:
            verts, joints = _expected(model, motion, k)
            want = (verts[ids] + [0.0, lift, 0.0]) * 100.0
            assert np.abs(got - want).max() < 5e-3  # centimetres: 0.05 mm
            np.testing.assert_allclose(reader.joint_positions(k)[1:], (joints + [0, lift, 0]) * 100, atol=5e-3)
    assert abs(lowest) < 1e-3  # the lowest vertex over the motion touches y = 0 (within 0.01 mm)


def test_morph_weights_every_frame(unreal):
    _, motion, path, report = unreal
    reader = GlbReader(path)
    anim = reader.gltf.animations[0]
    (channel,) = [c for c in anim.channels if c.target.path == "weights"]
    values = reader.array(anim.samplers[channel.sampler].output).reshape(motion.num_frames, -1)
    assert values.shape[1] == len(report.morph_targets) == 10
    np.testing.assert_array_equal(values, 0.0)  # the shape is baked in: betas rest at weight 0 in every key


def test_three_js_plays_the_engine_file(unreal):
    model, motion, path, report = unreal
    result = three_js(path, motion.fps, [5])
    _, joints = _expected(model, motion, 5)
    bones = np.array(result["bones"]["5"])
    np.testing.assert_allclose(bones[0], 0.0, atol=1e-6)  # the root bone stays at the origin
    np.testing.assert_allclose(bones[1:], (joints + [0, report.ground_lift, 0]) * 100, atol=5e-3)


def test_unity_metres_and_errors(tmp_path):
    model = open_model()
    motion = make_motion("smpl", seconds=0.2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        report = save_glb(tmp_path / "unity.glb", model, motion, engine="unity")
        exact = save_glb(tmp_path / "exact.glb", model, motion)
    assert report.unit_scale == 1.0 and exact.engine is None and exact.ground_lift is None
    assert [n.name for n in GlbReader(tmp_path / "exact.glb").gltf.nodes][-1] == "body"  # no root bone by default
    with pytest.raises(ValueError, match="engine: expected 'unreal', 'unity'"):
        save_glb(tmp_path / "x.glb", model, motion, engine="godot")
    with pytest.raises(ValueError, match="influences: engines take 4"):
        save_glb(tmp_path / "x.glb", model, motion, engine="unity", influences=8)
    with pytest.raises(ValueError, match="unit_scale: only with engine"):
        save_glb(tmp_path / "x.glb", model, motion, unit_scale=100)
