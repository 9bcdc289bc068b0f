"""Keypoint conventions: names and sizes, by-name conversion, masks, approximate pairs, synthesis."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import smplcore
from smplcore import keypoints as kp
from smplcore.errors import ShapeError

SIZES = {
    "coco17": 17,
    "openpose18": 18,
    "openpose25": 25,
    "openpose135": 135,
    "openpose137": 137,
    "coco_wholebody133": 133,
    "mediapipe33": 33,
    "mpii16": 16,
    "h36m17": 17,
    "smpl24": 24,
    "smpl45": 45,
    "smplh73": 73,
    "smplx127": 127,
    "smplx144": 144,
    "mano16": 16,
    "mano21": 21,
    "flame": 73,
}


@pytest.mark.parametrize("convention", sorted(SIZES))
def test_names_are_unique_and_have_the_published_size(convention):
    names = kp.names(convention)
    assert len(names) == SIZES[convention]
    assert len(set(names)) == len(names)
    assert all(isinstance(n, str) and n == n.strip() for n in names)


def test_smpl_family_conventions_are_smplcores_and_smplxs_output_orders():
    import smplx.joint_names as reference

    assert list(kp.names("smplx144")) == reference.JOINT_NAMES
    assert list(kp.names("smplx127")) == reference.JOINT_NAMES[:127]
    assert list(kp.names("smplh73")) == list(smplcore.joint_names.SMPLH_JOINT_NAMES)
    assert list(kp.names("smpl45")) == smplcore.BodyModel(model_type="open").joint_names


def test_published_orders_spot_checks():
    body25 = kp.names("openpose25")
    assert (body25[0], body25[1], body25[8], body25[15], body25[19], body25[24]) == (
        "nose",
        "neck",
        "mid_hip",
        "right_eye",
        "left_big_toe",
        "right_heel",
    )
    assert kp.own_names("openpose25")[:5] == ("Nose", "Neck", "RShoulder", "RElbow", "RWrist")
    assert kp.names("openpose135")[:17] == kp.names("coco17")
    assert kp.names("openpose135")[17:19] == ("upper_neck", "head_top")
    assert (
        kp.names("coco_wholebody133")[23] == "right_contour_1"
        and kp.names("coco_wholebody133")[91] == "left_wrist_hand"
    )
    assert kp.names("mediapipe33")[31] == "left_big_toe" and kp.own_names("mediapipe33")[31] == "left_foot_index"
    assert kp.names("mpii16")[9] == "head_top" and kp.names("h36m17")[10] == "head_top"
    assert kp.names("h36m17")[1:4] == ("left_hip", "left_knee", "left_ankle")  # SPIN's H36M_TO_J17 reading


def test_convention_aliases_and_unknown_convention():
    assert kp.names("BODY_25") == kp.names("openpose25")
    assert kp.names("H36M") == kp.names("h36m17")
    with pytest.raises(ValueError, match="convention: unknown keypoint convention 'coco18'"):
        kp.names("coco18")


def test_aliases_accept_the_conventions_own_spellings():
    assert kp.canonical("LShoulder") == "left_shoulder"
    assert kp.canonical("l_shoulder") == "left_shoulder"
    assert kp.canonical("OP MidHip") == "mid_hip"
    assert kp.canonical("LBigToe") == "left_big_toe"
    assert kp.canonical("leye") == "left_eye"
    assert kp.canonical("Left Hip") == "left_hip"
    # false friends resolve only within their convention
    assert kp.canonical("Head", "h36m17") == "head_top"
    assert kp.canonical("head") == "head"
    assert kp.canonical("left_pinky", "mediapipe33") == "left_pinky1"
    assert kp.canonical("left_pinky") == "left_pinky"
    assert kp.canonical("neck", "flame") == "flame_neck"


# hand-written from the published tables (SPIN's ALL_JOINTS_TO_COCO_MAP, SMPLify-X's smpl_to_openpose)
COCO_FROM_SMPL45 = [24, 26, 25, 28, 27, 16, 17, 18, 19, 20, 21, 1, 2, 4, 5, 7, 8]
COCO_FROM_SMPLX = [55, 57, 56, 59, 58, 16, 17, 18, 19, 20, 21, 1, 2, 4, 5, 7, 8]
# SMPLify-X puts SMPL's neck (12) and pelvis (0) at OpenPose's neck and mid-hip; smplcore uses OpenPose's
# definitions instead: the midpoints of the shoulders (16, 17) and of the hips (1, 2).
BODY25_FROM_SMPL45 = [24, (16, 17), 17, 19, 21, 16, 18, 20, (1, 2), 2, 5, 8, 1, 4, 7] + list(range(25, 35))
BODY25_FROM_SMPLX = [55, (16, 17), 17, 19, 21, 16, 18, 20, (1, 2), 2, 5, 8, 1, 4, 7] + list(range(56, 66))
LEFT_HAND_FROM_SMPLX = [20, 37, 38, 39, 66, 25, 26, 27, 67, 28, 29, 30, 68, 34, 35, 36, 69, 31, 32, 33, 70]


def _expected(points, table):
    rows = [
        points[..., i, :] if isinstance(i, int) else 0.5 * (points[..., i[0], :] + points[..., i[1], :]) for i in table
    ]
    return np.stack(rows, axis=-2)


@pytest.fixture(scope="module")
def smpl_output(fake_models):
    model = smplcore.BodyModel(fake_models["smpl_neutral_npz"], dtype=np.float64)
    rng = np.random.default_rng(0)
    return model, model(body_pose=rng.normal(0, 0.3, (2, 69)), betas=rng.normal(0, 1, (2, 10))).joints


@pytest.fixture(scope="module")
def smplx_output(fake_models):
    model = smplcore.BodyModel(fake_models["smplx_neutral_npz"], dtype=np.float64, use_face_contour=True)
    rng = np.random.default_rng(1)
    return model, model(body_pose=rng.normal(0, 0.3, (2, 63)), betas=rng.normal(0, 1, (2, 10))).joints


def test_coco17_and_body25_from_smpl_outputs_match_the_index_tables(smpl_output):
    model, joints = smpl_output
    assert joints.shape[1] == 45
    out, mask = kp.convert(joints, model, "coco17")
    np.testing.assert_array_equal(out, joints[:, COCO_FROM_SMPL45])
    assert mask.all()
    out, mask = kp.convert(joints, "smpl45", "openpose25")
    np.testing.assert_allclose(out, _expected(joints, BODY25_FROM_SMPL45), rtol=0, atol=1e-12)
    assert mask.all()


def test_coco17_body25_and_hands_from_smplx_outputs_match_the_index_tables(smplx_output):
    model, joints = smplx_output
    assert joints.shape[1] == 144
    out, mask = kp.convert(joints, model, "coco17")
    np.testing.assert_array_equal(out, joints[:, COCO_FROM_SMPLX])
    out, mask = kp.convert(joints, model, "openpose25")
    np.testing.assert_allclose(out, _expected(joints, BODY25_FROM_SMPLX), rtol=0, atol=1e-12)
    out, mask = kp.convert(joints, model, "openpose137")
    np.testing.assert_array_equal(out[:, 25:46], joints[:, LEFT_HAND_FROM_SMPLX])
    # the 68 face points: contour 127..143, then the 51 landmarks 76..126; the pupils approximated by the eyes
    np.testing.assert_array_equal(out[:, 67:135], joints[:, list(range(127, 144)) + list(range(76, 127))])
    np.testing.assert_array_equal(out[:, 135:137], joints[:, [56, 57]])
    assert mask.all()


def test_exact_only_masks_the_approximate_pairs(smpl_output):
    _, joints = smpl_output
    out, mask = kp.convert(joints, "smpl45", "coco17", exact_only=True)
    masked = [kp.names("coco17").index(n) for n in ("left_hip", "right_hip")]
    assert not mask[masked].any() and mask.sum() == 15
    assert np.all(out[:, masked] == 0)
    p = kp.plan("smpl45", "openpose25", exact_only=True)
    how = dict(zip(kp.names("openpose25"), p.how, strict=True))
    assert how["neck"] == "synthesised" and how["mid_hip"] == "missing" and how["left_hip"] == "missing"
    assert how["nose"] == "exact"


def test_approximate_pair_table():
    rows = {(c, r.name): r for r in kp.APPROXIMATE for c in r.conventions}
    assert rows[("coco17", "left_hip")].like == "left_hip" and rows[("coco17", "left_hip")].definition == "coco"
    assert rows[("openpose25", "mid_hip")].like == "pelvis"
    assert rows[("h36m17", "neck_nose")].like == "head"
    assert ("smpl24", "left_hip") not in rows
    # COCO-style hips are one definition: coco17 <-> openpose25 hips are exact, SMPL -> COCO hips are not
    assert kp.plan("openpose25", "coco17").how[11] == "exact"
    assert kp.plan("smpl24", "coco17").how[11] == "approximate"
    # SMPL's pelvis from OpenPose is approximate (mid-hip), SMPL's head from H36M is approximate (Neck/Nose)
    assert kp.plan("openpose25", "smpl24").how[0] == "approximate"
    assert kp.plan("h36m17", "smpl24").first[15] == kp.names("h36m17").index("neck_nose")
    # H36M's "Head" (the top of the head) is never used for SMPL's head joint
    assert kp.plan("smpl24", "h36m17").how[10] == "missing"
    assert ("h36m17", "Head") in kp.FALSE_FRIENDS
    for r in kp.APPROXIMATE:
        assert r.note and all(r.name in kp.names(c) for c in r.conventions)


def test_synthesis_is_exact_only_from_the_same_definitions():
    x = np.arange(17 * 3, dtype=np.float64).reshape(17, 3)
    out, mask = kp.convert(x, "coco17", "openpose25")
    np.testing.assert_array_equal(out[1], 0.5 * (x[5] + x[6]))  # neck: COCO's shoulders
    np.testing.assert_array_equal(out[8], 0.5 * (x[11] + x[12]))  # mid-hip: COCO's hips, same definition
    assert kp.plan("coco17", "openpose25").how[8] == "synthesised"
    assert not mask[19:].any() and mask[:19].all()  # COCO has no feet


@pytest.mark.parametrize("a, b", list(itertools.permutations(sorted(SIZES), 2))[::5])
def test_round_trip_is_the_identity_on_the_shared_names(a, b):
    from smplcore.keypoints.approximate import definition

    names_a, names_b = kp.names(a), kp.names(b)
    shared = [i for i, n in enumerate(names_a) if n in names_b and definition(a, n) == definition(b, n)]
    x = np.random.default_rng(2).normal(size=(3, len(names_a), 3))
    y, _ = kp.convert(x, a, b, exact_only=True)
    z, back = kp.convert(y, b, a, exact_only=True)
    np.testing.assert_array_equal(z[:, shared], x[:, shared])
    assert back[shared].all()


def test_round_trip_coco_body25_coco():
    x = np.random.default_rng(3).normal(size=(4, 17, 3))
    y, _ = kp.convert(x, "coco17", "openpose25")
    z, mask = kp.convert(y, "openpose25", "coco17")
    np.testing.assert_array_equal(z, x)
    assert mask.all()


def test_torch_points_keep_type_device_and_gradients(smpl_output):
    torch = pytest.importorskip("torch")
    _, joints = smpl_output
    t = torch.tensor(joints, dtype=torch.float64, requires_grad=True)
    out, mask = kp.convert(t, "smpl45", "openpose25")
    assert isinstance(out, torch.Tensor) and out.dtype == torch.float64 and mask.dtype == torch.bool
    np.testing.assert_allclose(out.detach().numpy(), kp.convert(joints, "smpl45", "openpose25")[0], atol=1e-12)
    out.sum().backward()
    assert t.grad is not None and float(t.grad.abs().sum()) > 0


def test_model_and_name_list_sources_and_bad_shapes():
    model = smplcore.BodyModel(model_type="open")
    joints = model().joints
    out, mask = kp.convert(joints, model, ["LShoulder", "RShoulder", "h36m17:head_top"])
    np.testing.assert_array_equal(out[0, :2], joints[0, [16, 17]])
    assert mask.tolist() == [True, True, False]
    with pytest.raises(ShapeError, match=r"points: expected shape \(\.\.\., 17, D\)"):
        kp.convert(np.zeros((2, 25, 3)), "coco17", "smpl24")
    with pytest.raises(TypeError, match="src: expected a convention name"):
        kp.convert(joints, 3, "coco17")


def test_keypoints_never_import_torch():
    import subprocess
    import sys

    code = (
        "import sys, numpy as np; from smplcore import keypoints as kp; "
        "kp.convert(np.zeros((2, 45, 3)), 'smpl45', 'openpose25'); "
        "kp.open_model_regressor('coco17').apply(np.zeros((13380, 3))); "
        "assert 'torch' not in sys.modules, 'torch was imported'"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
