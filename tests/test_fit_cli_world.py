"""``smplcore fit`` of 2D keypoints writes bodies in a Y-up world (feet on the ground, facing the camera) with
the camera's extrinsics recorded, so that export / render / view show them upright (issue 31, item 1); the
recorded model type is the model fitted (item 2); ``--max-iter`` and a truthful convergence report (item 3)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import smplcore
from export_helpers import GlbReader
from fakes_fit2d import natural_poses, scene, write_openpose
from smplcore import fit
from smplcore import keypoints as kp
from smplcore.cli import main
from smplcore.motion import load_motion


@pytest.fixture(scope="module")
def open_model():
    return smplcore.BodyModel(model_type="open", dtype=np.float64)


@pytest.fixture(scope="module")
def fitted(open_model, tmp_path_factory):
    """A 3-frame OpenPose sequence of one person seen by a camera (f = 1000 px) and its CLI fit."""
    root = tmp_path_factory.mktemp("world")
    rng = np.random.default_rng(7)
    seq = {k: np.repeat(v, 3, 0) for k, v in natural_poses(open_model, 1, rng).items()}
    frames, _, _ = scene(open_model, seq, np.random.default_rng(0), convention="openpose25")
    write_openpose(root / "op", frames)
    out = root / "fit.npz"
    assert main(["fit", str(root / "op"), "-o", str(out), "--focal", "1000", "--center", "500,500"]) == 0
    return root, out, frames


def _world_joints(model, path):
    motion = load_motion(path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # our own output: no shape-space warning (item 2)
        params = motion.model_params("open")
    out = model(**params)
    return np.asarray(out.vertices, np.float64), np.asarray(out.joints, np.float64)


def test_a_2d_fit_is_written_upright_on_the_ground_facing_the_camera(open_model, fitted):
    _, out, frames = fitted
    verts, joints = _world_joints(open_model, out)
    with np.load(out) as data:
        extrinsics = data["camera_extrinsics"]
        intrinsics = data["camera_intrinsics"]
        assert str(data["fit_frame"]) == "world"
        orient = data["poses"][:, :3]
    assert extrinsics.shape == (3, 4, 4) and intrinsics.shape == (3, 3, 3)
    np.testing.assert_allclose(intrinsics[:, :2, :2], np.tile(np.eye(2) * 1000.0, (3, 1, 1)))
    assert abs(verts[..., 1].min()) < 1e-6  # the lowest point of the sequence on the ground, y = 0
    np.testing.assert_allclose(joints[0, 0, [0, 2]], 0.0, atol=1e-6)  # the first frame's pelvis above the origin
    up = Rotation.from_rotvec(orient).apply([0.0, 1.0, 0.0])
    front = Rotation.from_rotvec(orient).apply([0.0, 0.0, 1.0])
    assert np.all(up[:, 1] > 0.9), up  # upright (the fixture's people lean by up to ~15-25 degrees)
    rotation, translation = extrinsics[:, :3, :3], extrinsics[:, :3, 3]
    eye = -np.einsum("tji,tj->ti", rotation, translation)  # camera centres in the world
    to_camera = eye - joints[:, 0]
    to_camera /= np.linalg.norm(to_camera, axis=1, keepdims=True)
    assert np.all(np.sum(front * to_camera, axis=1) > 0.8)  # facing the camera
    assert np.all(eye[:, 2] > 2.0) and np.all(np.abs(eye[:, 1] - joints[:, 0, 1]) < 1.0)  # in front, level-ish
    # the recorded camera sees the world bodies where the keypoints are
    openpose = kp.convert(joints, open_model, "openpose25")[0]
    cam = openpose @ np.swapaxes(rotation, 1, 2) + translation[:, None]
    uv = (cam @ np.swapaxes(intrinsics, 1, 2))[..., :2] / cam[..., 2:]
    seen = frames[..., 2] > 0
    assert np.linalg.norm(uv - frames[..., :2], axis=-1)[seen].mean() < 2.0


def test_the_exported_root_is_upright_facing_the_camera(fitted):
    root, out, _ = fitted
    glb = root / "fit.glb"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["export", str(out), "-o", str(glb)]) == 0
    trans, quat = GlbReader(glb).node_trs(0)
    rot = Rotation.from_quat(quat[0])  # node 0: the root joint
    assert rot.apply([0.0, 1.0, 0.0])[1] > 0.9  # not rotated 180 degrees about X
    assert rot.apply([0.0, 0.0, 1.0])[2] > 0.8  # facing +Z, where the camera is
    assert 0.6 < trans[0, 1] < 1.3 and np.hypot(trans[0, 0], trans[0, 2]) < 1e-3  # pelvis height, at the origin


def test_given_extrinsics_define_the_world(open_model, tmp_path):
    """A camera 4 m away, 1.3 m up, turned 25 degrees about Y: the fit comes out in that world."""
    turn = Rotation.from_euler("y", 25, degrees=True).as_matrix()
    eye = turn @ np.array([0.0, 1.3, 4.0])
    rotation = np.diag([1.0, -1.0, -1.0]) @ turn.T  # world to camera: level, looking at -Z turned
    translation = -rotation @ eye
    camera = fit.Camera(focal=1000.0, center=(500.0, 500.0), rotation=rotation, translation=translation)
    rng = np.random.default_rng(3)
    truth = natural_poses(open_model, 2, rng)
    truth["global_orient"] = Rotation.from_euler("y", [[20.0], [30.0]], degrees=True).as_rotvec()
    truth["transl"] = np.array([[0.1, 0.0, 0.0], [0.2, 0.0, 0.1]])
    keypoints, _, _ = scene(open_model, truth, rng, convention="openpose25", camera=camera)
    write_openpose(tmp_path / "op", keypoints)
    matrix = np.vstack([np.c_[rotation, translation], [0, 0, 0, 1]])
    text = ",".join(f"{v:.12g}" for v in matrix.reshape(-1))
    out = tmp_path / "fit.npz"
    assert main(["fit", str(tmp_path / "op"), "-o", str(out), "--focal", "1000", "--center", "500,500",
                 "--extrinsics", text]) == 0  # fmt: skip
    np.save(tmp_path / "extrinsics.npy", matrix[:3])  # a file holding (3, 4) works too
    out2 = tmp_path / "fit2.npz"
    assert main(["fit", str(tmp_path / "op"), "-o", str(out2), "--focal", "1000", "--center", "500,500",
                 "--extrinsics", str(tmp_path / "extrinsics.npy")]) == 0  # fmt: skip
    with np.load(out) as data, np.load(out2) as data2:
        np.testing.assert_allclose(data["camera_extrinsics"], np.tile(matrix, (2, 1, 1)), atol=1e-9)
        np.testing.assert_allclose(data2["poses"], data["poses"], atol=1e-9)
        orient = data["poses"][:, :3]
    angle = (Rotation.from_rotvec(orient) * Rotation.from_rotvec(truth["global_orient"]).inv()).magnitude()
    assert np.all(np.degrees(angle) < 15.0), np.degrees(angle)
    _, joints = _world_joints(open_model, out)
    true_joints = np.asarray(open_model(**truth).joints, np.float64)
    assert np.all(np.linalg.norm(joints[:, 0] - true_joints[:, 0], axis=1) < 0.4)  # depth is the loose part


@pytest.mark.parametrize("value", ["1,2,3", "1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,2", "nope.npy"])
def test_bad_extrinsics_are_argument_errors(tmp_path, value, capsys):
    (tmp_path / "op").mkdir()
    (tmp_path / "op" / "a_keypoints.json").write_text('{"people": []}')
    with pytest.raises(SystemExit) as exc:
        main(["fit", str(tmp_path / "op"), "-o", str(tmp_path / "x.npz"), "--focal", "1000", "--center", "5,5",
              "--extrinsics", value])  # fmt: skip
    assert exc.value.code == 2
    assert "--extrinsics" in capsys.readouterr().err


def test_the_open_model_fit_records_the_open_model(fitted):
    _, out, _ = fitted
    motion = load_motion(out)
    assert motion.model_type == "open" and motion.poses.shape == (3, 72)


def test_max_iter_is_passed_and_convergence_reported_truthfully(fitted, capsys):
    root, _, _ = fitted
    out = root / "short.npz"
    assert main(["fit", str(root / "op"), "-o", str(out), "--focal", "1000", "--center", "500,500",
                 "--max-iter", "1"]) == 0  # fmt: skip
    printed = capsys.readouterr().out
    with np.load(out) as data:
        assert not data["fit_converged"].any()  # one iteration per round cannot settle
    assert "iteration budget" in printed and "--max-iter 1" in printed, printed
    assert "1 with frames not converged" not in printed


@pytest.fixture()
def openpose_folder(fitted):
    return str(fitted[0] / "op")


def test_focal_without_a_principal_point_is_an_argument_error(openpose_folder, tmp_path, capsys):
    out = tmp_path / "x.npz"
    assert main(["fit", openpose_folder, "-o", str(out), "--focal", "1000"]) == 2
    err = capsys.readouterr().err
    assert "--center" in err and "skipped" not in err and not out.exists()


@pytest.mark.parametrize("focal", ["-1000", "0", "nan", "abc"])
def test_a_focal_length_that_is_not_positive_exits_2_at_parsing(openpose_folder, tmp_path, focal, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["fit", openpose_folder, "-o", str(tmp_path / "x.npz"), f"--focal={focal}", "--center", "640,360"])
    assert exc.value.code == 2 and "--focal" in capsys.readouterr().err


@pytest.mark.parametrize("focal", ["1e9", "1"])
def test_absurd_focal_lengths_are_refused_with_the_field_of_view(openpose_folder, tmp_path, focal, capsys):
    out = tmp_path / "x.npz"
    assert main(["fit", openpose_folder, "-o", str(out), "--focal", focal, "--center", "640,360"]) == 2
    err = capsys.readouterr().err
    assert f"--focal {float(focal):g}" in err and "field of view" in err and "pixels" in err and not out.exists()


def test_an_unusual_focal_length_is_warned_about(openpose_folder, tmp_path, capsys):
    out = tmp_path / "x.npz"
    args = ["fit", openpose_folder, "-o", str(out), "--focal", "200", "--center", "500,500", "--max-iter", "2"]
    assert main(args) == 0
    assert "warning: --focal 200: a 148° field of view" in capsys.readouterr().err
