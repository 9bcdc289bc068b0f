"""Skeleton maps: every map resolves against the open model, maps are found from joint names / point counts,
targets are built in metres with Y up (offsets in the parent's frame, blends), units and axes are detected from
the size (centimetres never pass silently), bone-length diagnostics; real clips when the shared mocap is present."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import smplcore
from smplcore import keypoints, skeletons
from smplcore.skeletons import BVHClip, SkeletonMap, Target, parse_bvh, to_model_targets
from smplcore.skeletons.diagnostics import bone_lengths
from smplcore.skeletons.units import AXES, decide_units, parse_units

MOCAP = Path("/work/shared/data/mocap")


@pytest.fixture(scope="module")
def model():
    return smplcore.BodyModel(model_type="open", dtype=np.float64)


@pytest.mark.parametrize("name", list(skeletons.MAPS))
def test_every_map_resolves_against_the_open_model(name, model):
    m = skeletons.skeleton_map(name)
    resolved = m.resolve(model)
    assert resolved.targets == m.targets  # nothing lost: every target is a joint of the open model
    assert set(m.joint_names) <= set(model.joint_names)
    used = {p for t in m.targets for p in t.points}
    assert used <= set(m.points), f"{name}: targets use points the skeleton does not list: {used - set(m.points)}"
    dropped = {p for p, _ in m.dropped}
    assert dropped | used == set(m.points) and not dropped & used  # every point is used or dropped, with a reason
    assert all(reason for _, reason in m.dropped)
    assert {"left_hip", "left_knee", "left_ankle", "right_hip", "right_knee", "right_ankle"} <= set(m.joint_names)
    if name != "smpl":
        assert "pelvis" not in m.joint_names  # no real skeleton's root is the model's pelvis (measured: maps.py)
    if m.kind == "points":
        assert not any(any(t.offset) for t in m.targets)  # offsets need joint frames
    assert name in m.describe()


def test_keypoint_maps_use_the_keypoints_conventions():
    assert skeletons.skeleton_map("h36m17").points == keypoints.names("h36m17")
    assert skeletons.skeleton_map("mediapipe").points == keypoints.names("mediapipe33")
    assert skeletons.skeleton_map("body25").points == keypoints.names("openpose25")
    h32 = skeletons.skeleton_map("h36m32").points
    assert len(h32) == 32 and h32[1] == "RightUpLeg" and h32[6] == "LeftUpLeg"


def test_cmu_neck_is_mapped_to_the_head_joint():
    for name in ("cmu_mb", "cmu_max"):
        assert skeletons.skeleton_map(name).source_of("neck").points == ("Head",)


def test_detection_from_joint_names_and_point_counts():
    for name in ("cmu_daz", "cmu_mb", "cmu_max", "fair"):
        m = skeletons.skeleton_map(name)
        assert skeletons.detect_skeleton(m.points).name == name
        assert skeletons.detect_skeleton(list(m.points) + ["extraJoint"]).name == name
    with pytest.raises(ValueError, match="no known skeleton has the joints root, a, b"):
        skeletons.detect_skeleton(["root", "a", "b"])
    assert skeletons.skeleton_for_points(17).name == "h36m17"
    assert skeletons.skeleton_for_points(33).name == "mediapipe33"
    with pytest.raises(ValueError, match="no keypoint skeleton has 5 points"):
        skeletons.skeleton_for_points(5)
    with pytest.raises(ValueError, match="unknown skeleton 'nope'"):
        skeletons.skeleton_map("nope")


def test_units_are_told_from_the_leg():
    assert decide_units(82.0, "y").name == "cm"
    assert decide_units(0.82, "y").name == "m"
    assert decide_units(820.0, "y").name == "mm"
    assert decide_units(14.5, "y").name == "cmu"
    assert decide_units(32.0, "y").name == "in"
    fair = decide_units(21.7, "z")
    assert fair.name == "estimated" and fair.scale == pytest.approx(0.8 / 21.7) and "unknown" in fair.message
    assert "centimetres (detected" in decide_units(82.0, "y").message
    given = decide_units(82.0, "y", units="cm")
    assert not given.detected and "(given)" in given.message
    assert parse_units("0.0375") == (0.0375, "given") and parse_units("CMU")[1] == "cmu"
    with pytest.raises(ValueError, match="units: expected one of"):
        parse_units("furlongs")
    with pytest.raises(ValueError, match="positive"):
        parse_units(-1.0)
    for up, axes in AXES.items():
        direction = np.zeros(3)
        direction["xyz".index(up[-1])] = -1.0 if up.startswith("-") else 1.0
        np.testing.assert_allclose(axes @ direction, [0, 1, 0], atol=1e-12)
        assert np.linalg.det(axes) == pytest.approx(1.0)


def _tiny_cm_bvh(up: str = "y") -> str:
    """A stick person in centimetres (leg 82 cm), Y up or Z up, facing +Z (or -Y for Z up)."""

    def v(x, y, z):  # a Y-up offset, written in the file's axes
        return f"{x} {y} {z}" if up == "y" else f"{x} {-z} {y}"

    joint = "JOINT {name}\n{{\nOFFSET {off}\nCHANNELS 3 Zrotation Xrotation Yrotation\n{body}}}\n"

    def leg(s, x):
        return joint.format(
            name=f"{s}Thigh",
            off=v(x, -2, 0),
            body=joint.format(
                name=f"{s}Shin",
                off=v(0, -40, 0),
                body=joint.format(name=f"{s}Foot", off=v(0, -42, 0), body=f"End Site\n{{\nOFFSET {v(0, -4, 12)}\n}}\n"),
            ),
        )  # noqa: E731

    def arm(s, x):
        return joint.format(
            name=f"{s}Shldr",
            off=v(x, 44, -1),
            body=joint.format(
                name=f"{s}ForeArm",
                off=v(x * 2.5, 0, 0),
                body=joint.format(
                    name=f"{s}Hand", off=v(x * 2.5, 0, 0), body=f"End Site\n{{\nOFFSET {v(x, 0, 0)}\n}}\n"
                ),
            ),
        )  # noqa: E731

    neck = joint.format(name="neck", off=v(0, 52, 0), body=f"End Site\n{{\nOFFSET {v(0, 10, 0)}\n}}\n")
    body = leg("l", 9) + leg("r", -9) + arm("l", 10) + arm("r", -10) + neck
    frames = "\n".join(" ".join(["0"] * (3 + 3 + 3 * 13)) for _ in range(2))
    return (f"HIERARCHY\nROOT hip\n{{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation "
            f"Yrotation\n{body}}}\nMOTION\nFrames: 2\nFrame Time: 0.0083333\n{frames}\n")  # fmt: skip


def _stick_map() -> SkeletonMap:
    from smplcore.skeletons.mapping import lr, sided

    targets = (
        *sided("hip", *lr("{s}Thigh")),
        *sided("knee", *lr("{s}Shin")),
        *sided("ankle", *lr("{s}Foot")),
        *sided("shoulder", *lr("{s}Shldr"), offset=(0.05, 0.0, 0.01)),
        *sided("wrist", *lr("{s}Hand")),
        Target("neck", ("neck", "neck_end"), blend=(3, 1)),
    )
    points = ("hip", "lThigh", "lShin", "lFoot", "rThigh", "rShin", "rFoot", "lShldr", "lForeArm", "lHand", "rShldr",
              "rForeArm", "rHand", "neck")  # fmt: skip
    return SkeletonMap("stick", "a test skeleton", "bvh", points, targets, (), "y", "cm")


@pytest.mark.parametrize("up", ["y", "z"])
def test_bvh_targets_in_metres_y_up_with_offsets_and_blends(up, model):
    clip = parse_bvh(_tiny_cm_bvh(up))
    t = to_model_targets(clip, _stick_map(), model)
    joints, names, weights = t  # unpacks for fit_joints
    assert joints.shape == (2, 11, 3) and weights.shape == (11,)
    assert "centimetres (detected: the leg, hip to ankle, is 82 units = 0.82 m)" in t.message
    assert f"up axis {up}" in t.message
    at = dict(zip(names, joints[0]))
    np.testing.assert_allclose(at["left_hip"], [0.09, -0.02, 0], atol=1e-12)
    np.testing.assert_allclose(at["left_ankle"], [0.09, -0.84, 0], atol=1e-12)
    np.testing.assert_allclose(at["left_shoulder"], [0.15, 0.44, 0.0], atol=1e-12)  # (0.10, 0.44, -0.01) moved
    np.testing.assert_allclose(at["right_shoulder"], [-0.15, 0.44, 0.0], atol=1e-12)  # mirrored
    np.testing.assert_allclose(at["neck"], [0, 0.545, 0], atol=1e-12)  # 3/4 neck + 1/4 its end


def test_offsets_follow_the_parent_frame(model):
    text = _tiny_cm_bvh("y").splitlines()
    # turn the root 90 degrees about Y in frame 1: the shoulder's offset (x out, z forward) turns with it
    text[-1] = "0 0 0 0 0 90 " + " ".join(["0"] * 39)
    clip = parse_bvh("\n".join(text) + "\n")
    assert clip.reference_pose  # (frame 0 at rest, the root turned after: it looks like a reference pose)
    t = to_model_targets(clip, _stick_map(), model, drop_reference_pose=False)
    at = dict(zip(t.joint_names, t.joints[1]))
    np.testing.assert_allclose(at["left_shoulder"], [0.0, 0.44, -0.15], atol=1e-12)


def test_points_targets_millimetres_z_up(model):
    rng = np.random.default_rng(0)
    out = model(body_pose=rng.normal(scale=0.1, size=(3, 69)))
    h36m, mask = keypoints.convert(out.joints, model, "h36m17")
    zup = np.linalg.inv(AXES["z"])  # Human3.6M's world: Z up, millimetres
    source = 1000.0 * h36m @ zup.T
    t = to_model_targets(source, None, model)
    assert t.skeleton.name == "h36m17" and "millimetres (detected" in t.message and "up axis z" in t.message
    at = dict(zip(t.joint_names, t.joints[0]))
    np.testing.assert_allclose(at["left_knee"], out.joints[0, model.joint_names.index("left_knee")], atol=1e-9)


def test_centimetre_points_never_pass_silently(model):
    joints = model(body_pose=np.zeros((1, 69))).joints[:, :24] * 100.0
    u = skeletons.points_units(joints, model.joint_names[:24])
    assert u.name == "cm" and u.scale == 0.01 and "centimetres" in u.message


def test_bone_lengths_of_the_models_own_body_are_in_reach(model):
    betas = np.array([[1.5, -1.0, 0.5] + [0.0] * 7])
    names = ["left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle", "left_shoulder",
             "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist", "neck"]  # fmt: skip
    joints = model(betas=betas).joints[:, [model.joint_names.index(n) for n in names]]
    report = bone_lengths(model, joints, names)
    assert report.ok and np.abs(report.off).max() < 0.005, str(report)
    assert ("hips", "neck") in report.bones
    np.testing.assert_allclose(report.betas[:3], betas[0, :3], atol=0.1)


def test_a_short_torso_is_reported_out_of_reach(model):
    names = ["left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle", "neck"]
    joints = model().joints[:, [model.joint_names.index(n) for n in names]].copy()
    joints[:, -1, 1] -= 0.18  # the neck 18 cm lower: a CMU-like torso
    report = bone_lengths(model, joints, names)
    assert ("hips", "neck") in report.out_of_reach
    k = report.bones.index(("hips", "neck"))
    assert report.beyond[k] < -0.05
    text = str(report)
    assert "OUT OF REACH" in text and "hips->neck by" in text and "(shorter)" in text


def _real(path: str) -> Path:
    p = MOCAP / path
    if not p.is_file():
        pytest.skip(f"the shared mocap ({p}) is absent")
    return p


@pytest.mark.parametrize(
    "path,name,units",
    [
        ("cmu_daz_ateliercircle/02_01.bvh.gz", "cmu_daz", "cm"),
        ("cmu_mb_jonathanalderson/06_01.bvh.gz", "cmu_mb", "cmu"),
        ("cmu_max_bvh11/131_02.bvh.gz", "cmu_max", "cmu"),
        ("fair_animateddrawings/dab.bvh.gz", "fair", "estimated"),
    ],
)
def test_real_clips_detected(path, name, units, model):
    t = to_model_targets(_real(path), model=model)
    assert t.skeleton.name == name and t.units.name == units
    assert isinstance(t.fps, float) and t.joints.shape[1:] == (len(t.joint_names), 3)
    heights = t.joints[..., 1]
    stature = np.median(heights.max(1) - heights.min(1))
    assert 1.0 < stature < 1.9  # ankles to neck / head, metres: a person, upright
    clip: BVHClip = skeletons.read_bvh(_real(path))
    assert t.joints.shape[0] == clip.num_frames - int(clip.reference_pose)
