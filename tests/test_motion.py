"""Motion sequences: reading AMASS-style files, slicing, resampling, picking the gendered model."""

from __future__ import annotations

import numpy as np
import pytest

import fakes
from smplcore.errors import ModelFileError
from smplcore.io.locate import locate_model_file
from smplcore.motion import Motion, load_motion, motion_from_arrays, pick_gender, resample_plan, save_motion
from smplcore.motion.models import Evaluator, ModelCache, normalize_gender
from smplcore.motion.resample import quat_to_rotvec, rotvec_to_quat, slerp_rotvec
from smplcore.motion.synthetic import random_arrays, write_sequence


def _rotmat(rotvec):
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(np.asarray(rotvec).reshape(-1, 3)).as_matrix()


# ------------------------------------------------------------------------------------------------
# Reading


def test_load_smplh_and_smplx_files(tmp_path):
    h = load_motion(write_sequence(tmp_path / "h.npz", 30, 120, "smplh", "male"))
    assert (h.model_type, h.gender, h.fps, h.num_frames) == ("smplh", "male", 120.0, 30)
    assert h.poses.shape == (30, 156) and h.betas.shape == (16,) and h.dmpls.shape == (30, 8)
    x = load_motion(write_sequence(tmp_path / "x.npz", 20, 60, "smplx", "female"))
    assert (x.model_type, x.gender, x.fps, x.poses.shape) == ("smplx", "female", 60.0, (20, 165))


def test_load_reads_only_motion_keys(tmp_path):
    """AMASS SMPL-X files carry extra keys (marker dicts as object arrays): they are not read."""
    arrays = random_arrays(10, 120, "smplx", "neutral")
    arrays["markers_latent_vids"] = np.array({"C7": 3832}, dtype=object)
    arrays["gender"] = np.array(b"neutral")  # bytes, as in some AMASS files
    np.savez(tmp_path / "a.npz", **arrays)
    m = load_motion(tmp_path / "a.npz")
    assert m.gender == "neutral" and m.num_frames == 10


@pytest.mark.parametrize(
    "damage, key",
    [
        ("truncate", None),
        ("trans_rows", "trans"),
        ("nan_poses", "poses"),
        ("nan_betas", "betas"),
        ("no_fps", "mocap_framerate"),
        ("dmpls_rows", "dmpls"),
    ],
)
def test_bad_files_name_file_and_key(tmp_path, damage, key):
    arrays = random_arrays(40, 120, "smplh", "female")
    path = tmp_path / f"{damage}.npz"
    if damage == "trans_rows":
        arrays["trans"] = arrays["trans"][:-3]
    elif damage == "nan_poses":
        arrays["poses"][5, 10] = np.nan
    elif damage == "nan_betas":
        arrays["betas"][2] = np.nan
    elif damage == "no_fps":
        del arrays["mocap_framerate"]
    elif damage == "dmpls_rows":
        arrays["dmpls"] = arrays["dmpls"][:5]
    np.savez(path, **arrays)
    if damage == "truncate":
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])
    with pytest.raises(ModelFileError) as info:
        load_motion(path)
    assert str(path) in str(info.value)
    assert info.value.key == key
    if damage == "truncate":
        assert "truncated or corrupt" in str(info.value)


def test_a_missing_frame_rate_is_refused_unless_given(tmp_path):
    """The one AMASS reader's policy: no silent guess of the frame rate; ``default_fps`` gives it."""
    arrays = random_arrays(12, 60, "smplx", "male")
    del arrays["mocap_frame_rate"]
    path = tmp_path / "x.npz"
    np.savez(path, **arrays)
    with pytest.raises(ModelFileError, match=r"missing the frame rate .*default_fps") as info:
        load_motion(path)
    assert info.value.key == "mocap_frame_rate" and str(path) in str(info.value)  # the key SMPL-X files use
    assert load_motion(path, default_fps=30.0).fps == 30.0
    assert motion_from_arrays(arrays, default_fps=25.0).fps == 25.0  # the same reader from arrays
    stated = random_arrays(12, 60, "smplh", "male")
    assert motion_from_arrays(stated, default_fps=25.0).fps == 60.0  # the file's rate wins


def test_save_load_round_trip(tmp_path):
    m = load_motion(write_sequence(tmp_path / "a.npz", 12, 60, "smplh", "female"))
    back = load_motion(save_motion(m, tmp_path / "b.npz"))
    np.testing.assert_array_equal(back.poses, m.poses)
    assert (back.fps, back.gender, back.model_type) == (m.fps, m.gender, m.model_type)


# ------------------------------------------------------------------------------------------------
# Slicing and resampling


def test_slice():
    m = Motion(np.arange(10 * 156, dtype=float).reshape(10, 156) * 1e-4, np.zeros((10, 3)), np.zeros(16), 120.0)
    s = m.slice(2, 8, 2)
    assert s.num_frames == 3 and s.fps == 60.0
    np.testing.assert_array_equal(s.poses, m.poses[2:8:2])


def test_stride_is_humanml3d_subsampling():
    for fps, step in ((120.0, 6), (60.0, 3), (59.94, 2), (100.0, 5), (30.0, 1), (10.0, 1)):
        p = resample_plan(101, fps, 20.0, "stride")
        np.testing.assert_array_equal(p.index, np.arange(0, 101, step))
        assert p.is_selection and p.fps == pytest.approx(fps / step)


def test_nearest_and_interp_hit_the_target_rate():
    p = resample_plan(121, 120.0, 20.0, "nearest")
    np.testing.assert_array_equal(p.index, np.arange(0, 121, 6))
    p = resample_plan(100, 30.0, 20.0, "nearest")  # positions 0, 1.5, 3, 4.5 ... ties go down
    np.testing.assert_array_equal(p.index[:4], [0, 1, 3, 4])
    assert p.fps == 20.0 and p.source_position[-1] <= 99
    q = resample_plan(100, 30.0, 20.0, "interp")
    np.testing.assert_allclose(q.source_position, np.arange(q.num_frames) * 1.5)
    assert q.num_frames == 67  # 0 .. 99 in steps of 1.5
    up = resample_plan(11, 10.0, 30.0, "interp")
    assert up.num_frames == 31 and up.source_position[-1] == pytest.approx(10.0)


def test_interp_keeps_source_frames_exactly_and_slerps_between():
    arrays = random_arrays(61, 60.0, "smplh", "female", seed=3)
    m = Motion(arrays["poses"], arrays["trans"], arrays["betas"], 60.0, dmpls=arrays["dmpls"])
    r = m.resample(30.0)
    assert r.fps == 30.0 and r.num_frames == 31
    np.testing.assert_array_equal(r.poses, m.poses[::2])
    np.testing.assert_array_equal(r.trans, m.trans[::2])
    half = m.resample(120.0)  # every other frame halfway between two source frames
    np.testing.assert_allclose(half.trans[1], (m.trans[0] + m.trans[1]) / 2)
    np.testing.assert_allclose(half.dmpls[1], (m.dmpls[0] + m.dmpls[1]) / 2)
    a, b, mid = m.poses[0].reshape(-1, 3), m.poses[1].reshape(-1, 3), half.poses[1].reshape(-1, 3)
    # The midpoint rotation R satisfies R = A (A^T B)^(1/2): check A^T R == R^T B.
    ra, rb, rm = _rotmat(a), _rotmat(b), _rotmat(mid)
    np.testing.assert_allclose(ra.transpose(0, 2, 1) @ rm, rm.transpose(0, 2, 1) @ rb, atol=1e-9)


def test_quaternion_helpers():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(200, 3))
    v *= rng.uniform(0, np.pi - 1e-3, size=(200, 1)) / np.linalg.norm(v, axis=1, keepdims=True)
    v[:3] = [[0, 0, 0], [1e-10, 0, 0], [0, 0, np.pi - 1e-6]]
    np.testing.assert_allclose(quat_to_rotvec(rotvec_to_quat(v)), v, atol=1e-9)
    np.testing.assert_allclose(_rotmat(slerp_rotvec(v, v, 0.3)), _rotmat(v), atol=1e-9)
    big = np.array([[0.0, 0.0, 1.5 * np.pi]])  # more than half a turn: same rotation, angle in [0, π]
    np.testing.assert_allclose(_rotmat(quat_to_rotvec(rotvec_to_quat(big))), _rotmat(big), atol=1e-12)


def test_resample_rejects_bad_rates():
    with pytest.raises(ValueError, match="fps"):
        resample_plan(10, 0.0, 20.0)
    with pytest.raises(ValueError, match="method"):
        resample_plan(10, 30.0, 20.0, "cubic")


# ------------------------------------------------------------------------------------------------
# The gendered model


def test_gender_rules():
    assert normalize_gender("Female") == "female" and normalize_gender(" M ") == "male"
    assert pick_gender("female") == "female" and pick_gender("neutral") == "neutral"
    assert pick_gender("neutral", "humanml3d") == "female" and pick_gender("male", "humanml3d") == "male"
    assert pick_gender("male", "neutral") == "neutral"
    with pytest.raises(ValueError, match="gender"):
        normalize_gender("robot")


def test_model_file_in_smplx_and_amass_layouts(tmp_path):
    smplx_style = fakes.write_smplh(tmp_path / "models" / "smplh", "female", "npz", amass=True)
    amass_style = fakes.write_smplh(tmp_path / "models" / "smplh", "male", "npz", amass=True, official_name=True)
    root = tmp_path / "models"
    assert locate_model_file(root, "smplh", gender="female") == smplx_style
    assert locate_model_file(root, "smplh", gender="male") == amass_style
    assert locate_model_file(root / "smplh", "smplh", gender="male") == amass_style  # the type folder itself
    assert locate_model_file(smplx_style, "smplh", gender="male") == smplx_style  # a file serves every gender
    with pytest.raises(ModelFileError, match=r"no neutral SMPL\+H model .*smplh/neutral/model.npz"):
        locate_model_file(root, "smplh", gender="neutral")

    cache = ModelCache(root, backend="numpy")
    f, m = cache.get("smplh", "female"), cache.get("smplh", "male")
    assert (f.gender, m.gender, f.num_betas) == ("female", "male", 16)
    assert cache.get("smplh", "female") is f and len(cache.models) == 2


def test_evaluator_chunks_match_one_call(tmp_path):
    path = fakes.write_smplh(tmp_path, "female", "npz", amass=True)
    motion = load_motion(write_sequence(tmp_path / "s.npz", 23, 30, "smplh", "female"))
    loaded = ModelCache(path, backend="numpy").get("smplh", "female")
    whole, _ = Evaluator(chunk=1000).run(motion, loaded)
    parts, verts = Evaluator(chunk=5, vertex_budget=7 * 6890).run(motion, loaded, vertices=True)
    np.testing.assert_allclose(parts, whole, atol=1e-6)
    assert verts.shape == (23, 6890, 3)
    direct = loaded.model(return_verts=True, **Evaluator().params(motion, loaded))
    np.testing.assert_allclose(verts, direct.vertices, atol=1e-5)
    np.testing.assert_allclose(whole, direct.joints, atol=1e-5)


@pytest.mark.parametrize("backend", ["numpy", "torch"])
def test_skeleton_only_path_equals_the_full_forward(tmp_path, backend):
    if backend == "torch":
        pytest.importorskip("torch")
    path = fakes.write_smplh(tmp_path, "male", "npz", amass=True)
    motion = load_motion(write_sequence(tmp_path / "s.npz", 37, 60, "smplh", "male"))
    loaded = ModelCache(path, backend=backend, num_betas=10).get("smplh", "male")
    full, _ = Evaluator(chunk=16).run(motion, loaded)
    skeleton, _ = Evaluator(chunk=16).run(motion, loaded, skeleton_only=True)
    assert skeleton.shape == (37, 52, 3)
    np.testing.assert_allclose(skeleton, full[:, :52], atol=1e-5)
