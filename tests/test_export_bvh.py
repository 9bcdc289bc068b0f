"""BVH export: a small independent parser + forward kinematics (and bvhio where installed) give back the
model's joints at every frame."""

from __future__ import annotations

import re

import numpy as np
import pytest

import smplcore
from export_helpers import make_motion, open_model
from smplcore.export import save_bvh
from smplcore.export.bvh import euler_angles

pytestmark = pytest.mark.filterwarnings("ignore:.*pose-corrective.*:UserWarning")


# --------------------------------------------------------------------------------------------------
# A minimal BVH reader, written from the format description (not from our writer).


def _axis_rotation(axis: str, degrees: np.ndarray) -> np.ndarray:
    a = np.radians(degrees)
    c, s = np.cos(a), np.sin(a)
    one, zero = np.ones_like(a), np.zeros_like(a)
    rows = {
        "X": [[one, zero, zero], [zero, c, -s], [zero, s, c]],
        "Y": [[c, zero, s], [zero, one, zero], [-s, zero, c]],
        "Z": [[c, -s, zero], [s, c, zero], [zero, zero, one]],
    }[axis]
    return np.moveaxis(np.array(rows), (0, 1), (-2, -1))


def read_bvh(path):
    tokens = re.split(r"\s+", path.read_text().strip())
    names, parents, offsets, channels, end_sites = [], [], [], [], {}
    stack, i = [], 1  # tokens[0] == "HIERARCHY"
    while tokens[i] != "MOTION":
        tok = tokens[i]
        if tok in ("ROOT", "JOINT"):
            names.append(tokens[i + 1])
            parents.append(stack[-1] if stack else -1)
            stack.append(len(names) - 1)
            i += 3  # name, "{"
        elif tok == "End":
            assert tokens[i + 1] == "Site" and tokens[i + 2] == "{" and tokens[i + 3] == "OFFSET"
            end_sites[names[stack[-1]]] = np.array(tokens[i + 4 : i + 7], float)
            assert tokens[i + 7] == "}"
            i += 8
        elif tok == "OFFSET":
            offsets.append(np.array(tokens[i + 1 : i + 4], float))
            i += 4
        elif tok == "CHANNELS":
            n = int(tokens[i + 1])
            channels.append(tokens[i + 2 : i + 2 + n])
            i += 2 + n
        elif tok == "}":
            stack.pop()
            i += 1
        else:
            raise AssertionError(f"unexpected token {tok!r}")
    assert tokens[i + 1] == "Frames:" and tokens[i + 3] == "Frame" and tokens[i + 4] == "Time:"
    frames, frame_time = int(tokens[i + 2]), float(tokens[i + 5])
    data = np.array(tokens[i + 6 :], float).reshape(frames, -1)
    return dict(
        names=names,
        parents=parents,
        offsets=np.array(offsets),
        channels=channels,
        end_sites=end_sites,
        frames=frames,
        frame_time=frame_time,
        data=data,
    )


def bvh_joint_positions(bvh, names=None) -> np.ndarray:
    """(T, J, 3) world joint positions by forward kinematics, ordered as ``names`` (default: the file's)."""
    data, frames = bvh["data"], bvh["frames"]
    count = len(bvh["names"])
    world_rot = np.zeros((frames, count, 3, 3))
    world_pos = np.zeros((frames, count, 3))
    col = 0
    for j, chans in enumerate(bvh["channels"]):
        local_rot = np.broadcast_to(np.eye(3), (frames, 3, 3))
        local_pos = np.broadcast_to(bvh["offsets"][j], (frames, 3)).copy()
        for name in chans:
            values = data[:, col]
            col += 1
            if name.endswith("position"):
                local_pos[:, "XYZ".index(name[0])] += values
            else:
                local_rot = local_rot @ _axis_rotation(name[0], values)
        parent = bvh["parents"][j]
        if parent < 0:
            world_rot[:, j], world_pos[:, j] = local_rot, local_pos
        else:
            world_rot[:, j] = world_rot[:, parent] @ local_rot
            world_pos[:, j] = world_pos[:, parent] + (world_rot[:, parent] @ local_pos[..., None])[..., 0]
    assert col == data.shape[1]
    if names is not None:
        world_pos = world_pos[:, [bvh["names"].index(n) for n in names]]
    return world_pos


def _model_joints(model, motion):
    params = motion.model_params(model.model_type, model.skeleton_joint_names)
    return model(**params).joints[:, : len(model.skeleton_joint_names)]


# --------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def smpl(fake_models):
    return smplcore.BodyModel(fake_models["smpl_neutral_pkl"])


@pytest.mark.parametrize("order", ["ZYX", "ZXY", "XYZ"])
def test_round_trip_every_frame(tmp_path, smpl, order):
    motion = make_motion("smpl", seconds=2.0, fps=30.0)
    report = save_bvh(tmp_path / "m.bvh", smpl, motion, euler=order)
    bvh = read_bvh(tmp_path / "m.bvh")
    names = smpl.skeleton_joint_names
    assert sorted(bvh["names"]) == sorted(names)  # depth-first in the file
    assert [bvh["names"][p] if p >= 0 else None for p in bvh["parents"]] == [
        names[smpl.parents[names.index(n)]] if n != names[0] else None for n in bvh["names"]
    ]
    assert bvh["frames"] == motion.num_frames == report.num_frames
    assert bvh["frame_time"] == pytest.approx(1 / 30, abs=1e-8)
    assert bvh["channels"][0] == ["Xposition", "Yposition", "Zposition"] + [f"{a}rotation" for a in order]
    assert all(c == [f"{a}rotation" for a in order] for c in bvh["channels"][1:])
    np.testing.assert_allclose(bvh_joint_positions(bvh, names), _model_joints(smpl, motion), atol=1e-4, rtol=0)
    # Offsets are the shaped rest pose's bones; the root's is zero (its position channels are absolute).
    _, rest = smpl.rest_pose(motion.betas)
    expected = rest - rest[np.maximum(smpl.parents, 0)]
    order_in_file = [names.index(n) for n in bvh["names"]]
    np.testing.assert_allclose(bvh["offsets"][1:], expected[order_in_file][1:], atol=1e-6)
    np.testing.assert_array_equal(bvh["offsets"][0], 0.0)
    # Every leaf joint ends in an End Site pointing away from its parent.
    leaves = [n for j, n in enumerate(smpl.skeleton_joint_names) if j not in set(smpl.parents.tolist())]
    assert sorted(bvh["end_sites"]) == sorted(leaves)
    for name, end in bvh["end_sites"].items():
        j = smpl.skeleton_joint_names.index(name)
        assert end @ expected[j] > 0


def test_angles_are_continuous(tmp_path, smpl):
    """The root turns by more than half a turn: no 360 degree jumps between frames."""
    motion = make_motion("smpl", seconds=3.0, fps=30.0)
    assert np.abs(motion.poses[-1, 1] - motion.poses[0, 1]) > np.pi
    save_bvh(tmp_path / "c.bvh", smpl, motion)
    data = read_bvh(tmp_path / "c.bvh")["data"][:, 3:]
    assert np.abs(np.diff(data, axis=0)).max() < 60.0
    # Plain conversions wrap at +-180 degrees and flip at gimbal limits; the file's angles do not.
    from scipy.spatial.transform import Rotation

    raw = Rotation.from_rotvec(motion.poses[:, :3]).as_euler("ZYX", degrees=True)
    assert np.abs(np.diff(raw, axis=0)).max() > 170.0  # (the root passes near gimbal lock, Y = 90 degrees)


def test_euler_angles_reproduce_rotations_near_gimbal_lock():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(2)
    rot = Rotation.from_euler(
        "ZYX",
        np.c_[rng.uniform(-180, 180, 40), np.linspace(85, 95, 40), rng.uniform(-180, 180, 40)],
        degrees=True,
    )
    mats = rot.as_matrix()[:, None]
    for order in ("ZYX", "YXZ"):
        angles = euler_angles(mats, order)[:, 0]
        back = np.ones((40, 3, 3)) * np.eye(3)
        for k, axis in enumerate(order):
            back = back @ _axis_rotation(axis, angles[:, k])
        np.testing.assert_allclose(back, mats[:, 0], atol=1e-9)


def test_scale_and_frame_rate(tmp_path, smpl):
    motion = make_motion("smpl", seconds=1.0, fps=120.0)
    save_bvh(tmp_path / "cm.bvh", smpl, motion, scale=100.0)
    bvh = read_bvh(tmp_path / "cm.bvh")
    assert bvh["frame_time"] == pytest.approx(1 / 120, abs=1e-8) and bvh["frames"] == 120
    np.testing.assert_allclose(
        bvh_joint_positions(bvh, smpl.skeleton_joint_names) / 100.0,
        _model_joints(smpl, motion),
        atol=1e-4,
        rtol=0,
    )
    save_bvh(tmp_path / "fps.bvh", smpl, motion, fps=60)
    assert read_bvh(tmp_path / "fps.bvh")["frame_time"] == pytest.approx(1 / 60, abs=1e-8)


def test_smplh_hands_and_parameter_sets(tmp_path, fake_models):
    model = smplcore.BodyModel(fake_models["smplh_female_npz"], use_pca=False, flat_hand_mean=True, num_betas=16)
    motion = make_motion("smplh", seconds=1.0, fps=30.0, num_betas=16)
    save_bvh(tmp_path / "h.bvh", model, motion)
    bvh = read_bvh(tmp_path / "h.bvh")
    assert len(bvh["names"]) == 52
    np.testing.assert_allclose(
        bvh_joint_positions(bvh, model.skeleton_joint_names), _model_joints(model, motion), atol=1e-4, rtol=0
    )
    # A model that adds its mean hand pose: the motion's hand poses are relative to it, as in the model.
    relative = smplcore.BodyModel(fake_models["smplh_female_npz"], use_pca=False, num_betas=16)
    assert np.any(relative.setup.pose_mean)
    save_bvh(tmp_path / "r.bvh", relative, motion)
    got = bvh_joint_positions(read_bvh(tmp_path / "r.bvh"), relative.skeleton_joint_names)
    np.testing.assert_allclose(got, _model_joints(relative, motion), atol=1e-4, rtol=0)
    # One parameter set (PCA hands, mean hand pose: through the model).
    pca = smplcore.BodyModel(fake_models["smplh_female_npz"], num_betas=16)
    rng = np.random.default_rng(1)
    params = {
        "betas": rng.normal(size=16),
        "body_pose": rng.normal(0, 0.3, 63),
        "left_hand_pose": rng.normal(size=6),
        "right_hand_pose": rng.normal(size=6),
        "transl": [0.1, 0.0, 0.5],
    }
    save_bvh(tmp_path / "p.bvh", pca, params)
    bvh = read_bvh(tmp_path / "p.bvh")
    assert bvh["frames"] == 1 and bvh["frame_time"] == pytest.approx(1 / 30, abs=1e-8)
    expected = pca(**{k: np.asarray(v)[None] for k, v in params.items()}).joints[:, :52]
    np.testing.assert_allclose(bvh_joint_positions(bvh, pca.skeleton_joint_names), expected, atol=1e-4, rtol=0)


def test_open_model(tmp_path):
    model = open_model()
    motion = make_motion("smpl", seconds=2.0, fps=30.0, seed=3)
    save_bvh(tmp_path / "o.bvh", model, motion)
    got = bvh_joint_positions(read_bvh(tmp_path / "o.bvh"), model.skeleton_joint_names)
    np.testing.assert_allclose(got, _model_joints(model, motion), atol=1e-4, rtol=0)


def test_bvhio_reads_it(tmp_path, smpl):
    """An existing BVH library (bvhio) reads the file and its forward kinematics agree."""
    bvhio = pytest.importorskip("bvhio", reason="bvhio is not installed (pip install bvhio)")
    motion = make_motion("smpl", seconds=1.0, fps=30.0, seed=5)
    save_bvh(tmp_path / "b.bvh", smpl, motion)
    root = bvhio.readAsHierarchy(str(tmp_path / "b.bvh"))
    expected = _model_joints(smpl, motion)
    for k in range(motion.num_frames):
        root.loadPose(k)
        positions = {joint.Name: np.array(joint.PositionWorld) for joint, *_ in root.layout()}
        got = np.array([positions[name] for name in smpl.skeleton_joint_names])
        np.testing.assert_allclose(got, expected[k], atol=1e-4, rtol=0)
