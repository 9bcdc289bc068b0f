"""``smplcore fit``: OpenPose / COCO / joints / motion inputs to AMASS-style .npz, batches, bad inputs."""

from __future__ import annotations

import json

import numpy as np
import pytest

import smplcore
from export_helpers import validate
from fakes_fit2d import CAMERA, natural_poses, scene, write_coco, write_openpose
from smplcore import keypoints as kp
from smplcore.cli import main
from smplcore.motion import load_motion


@pytest.fixture(scope="module")
def open_model():
    return smplcore.BodyModel(model_type="open", dtype=np.float64)


@pytest.fixture(scope="module")
def sequence(open_model):
    rng = np.random.default_rng(7)
    params = natural_poses(open_model, 1, rng)
    frames = 4
    seq = {k: np.repeat(v, frames, 0) for k, v in params.items()}
    seq["body_pose"] = seq["body_pose"] + np.linspace(0, 0.1, frames)[:, None]
    return seq


def _openpose_folder(folder, model, params):
    keypoints, _, _ = scene(model, params, np.random.default_rng(0), convention="openpose25")
    return write_openpose(folder, keypoints)


def test_openpose_folder_round_trip_to_glb(tmp_path, open_model, sequence, capsys):
    folder = _openpose_folder(tmp_path / "op", open_model, sequence)
    out = tmp_path / "fit.npz"
    assert main(["fit", str(folder), "-o", str(out), "--focal", "1000", "--center", "500,500", "--fps", "25"]) == 0
    assert "1 fitted, 0 skipped" in capsys.readouterr().out
    motion = load_motion(out)  # the motion reader of export / process
    assert motion.num_frames == 4 and motion.fps == 25.0 and motion.poses.shape == (4, 72)
    with np.load(out) as data:
        assert data["fit_error"].shape == (4,) and data["fit_error"].max() < 2.0  # pixels
    again = open_model(**motion.model_params("open"))
    with np.load(out) as data:  # the world of the output and the camera that sees it
        extrinsics = data["camera_extrinsics"][0]
    camera = smplcore.fit.Camera(CAMERA.focal, CAMERA.center, extrinsics[:3, :3], extrinsics[:3, 3])
    uv = camera.project(kp.convert(np.asarray(again.joints, np.float64), open_model, "openpose25")[0])
    target, _, _ = scene(open_model, sequence, np.random.default_rng(0), convention="openpose25")
    seen = target[..., 2] > 0
    assert np.linalg.norm(uv - target[..., :2], axis=-1)[seen].mean() < 2.0
    glb = tmp_path / "fit.glb"
    assert main(["export", str(out), "-o", str(glb)]) == 0
    assert validate(glb)["issues"]["numErrors"] == 0


def test_coco_file_cameras_from_image_sizes(tmp_path, open_model):
    rng = np.random.default_rng(2)
    params = natural_poses(open_model, 2, rng)
    cam = smplcore.fit.Camera.from_image_size(1000, 1000)
    keypoints, _, _ = scene(open_model, params, rng, camera=cam)
    path = write_coco(tmp_path / "people.json", keypoints, 1000, 1000, image_id=5)
    out = tmp_path / "people.npz"
    assert main(["fit", str(path), "-o", str(out)]) == 0
    with np.load(out) as data:
        assert data["poses"].shape == (2, 72)
        np.testing.assert_allclose(data["fit_focal"], np.hypot(1000, 1000))  # the image's diagonal, not estimated
        assert (
            list(data["person"]) == [0, 1] and data["fit_error"].max() < 5.0
        )  # pixels (the pipeline, not the accuracy)


def test_joints_npy_with_a_convention(tmp_path, open_model, sequence):
    joints = kp.convert(np.asarray(open_model(**sequence).joints, np.float64), open_model, "coco17")[0]
    path = tmp_path / "joints.npy"
    np.save(path, joints)
    out = tmp_path / "joints_fit.npz"
    assert main(["fit", str(path), "-o", str(out), "--convention", "coco17"]) == 0
    with np.load(out) as data:
        assert data["fit_error"].max() < 0.03  # metres, 15 exact joints (hips are approximate)


def test_joints_npy_with_joint_names(tmp_path, open_model, sequence):
    joints = np.asarray(open_model(**sequence).joints, np.float64)[:, :22]
    path = tmp_path / "j22.npy"
    np.save(path, joints)
    names = ",".join(open_model.joint_names[:22])
    out = tmp_path / "j22.npz"
    assert main(["fit", str(path), "-o", str(out), "--joint-names", names]) == 0
    with np.load(out) as data:
        assert data["fit_error"].max() < 0.005


def test_motion_conversion_to_itself(tmp_path, open_model, sequence):
    from smplcore.motion import Motion, save_motion

    poses = np.concatenate([sequence["global_orient"], sequence["body_pose"]], 1)
    motion = Motion(poses, sequence["transl"], sequence["betas"][0], 30.0, model_type="open")
    path = save_motion(motion, tmp_path / "walk.npz")
    out = tmp_path / "walk_fit.npz"
    assert main(["fit", str(path), "-o", str(out)]) == 0
    with np.load(out) as data:
        assert data["fit_error"].max() < 0.001


def test_a_folder_of_inputs_skips_bad_ones_and_resumes(tmp_path, open_model, sequence, capsys):
    inputs = tmp_path / "in"
    inputs.mkdir()
    _openpose_folder(inputs / "clip", open_model, sequence)
    np.save(inputs / "good.npy", np.asarray(open_model(**sequence).joints, np.float64)[:, :22])
    bad = np.asarray(open_model(**sequence).joints, np.float64)[:2, :22]
    bad[0] = np.nan  # a frame without any joint (a NaN joint alone is a missing marker, fitted around)
    np.save(inputs / "nan.npy", bad)
    (inputs / "broken.json").write_text("{not json")
    out = tmp_path / "out"
    argv = ["fit", str(inputs), "-o", str(out), "--focal", "1000", "--center", "500,500", "--workers", "2"]
    assert main(argv) == 1
    text = capsys.readouterr()
    assert "2 fitted, 2 skipped" in text.out
    assert "nan.npy" in text.err and "all NaN" in text.err and "broken.json" in text.err
    assert sorted(p.name for p in out.glob("*.npz")) == ["clip.npz", "good.npz"]
    manifest = json.loads((out / "fit_manifest.json").read_text())
    assert {e["status"] for e in manifest["entries"]} == {"done", "skipped"}
    assert not list(out.glob(".*smplcore-tmp"))
    assert main(argv) == 1  # the rerun keeps finished outputs, retries the bad ones
    assert "0 fitted, 2 skipped (bad input), 2 already done" in capsys.readouterr().out


def test_missing_camera_is_reported(tmp_path, open_model, sequence, capsys):
    folder = _openpose_folder(tmp_path / "op", open_model, sequence)
    assert main(["fit", str(folder), "-o", str(tmp_path / "x.npz")]) == 2  # an argument error, before any fit
    assert "camera" in capsys.readouterr().err
    assert not (tmp_path / "x.npz").exists()


def test_openpose_frames_without_the_person_take_the_nearest_fit(tmp_path, open_model, sequence):
    folder = _openpose_folder(tmp_path / "op", open_model, sequence)
    empty = folder / "frame_0002_keypoints.json"
    empty.write_text(json.dumps({"version": 1.3, "people": []}))
    out = tmp_path / "gap.npz"
    assert main(["fit", str(folder), "-o", str(out), "--focal", "1000", "--center", "500,500"]) == 0
    with np.load(out) as data:
        assert np.isnan(data["fit_error"][2]) and not data["fit_converged"][2]
        assert np.all(np.isfinite(data["fit_error"][[0, 1, 3]]))
        np.testing.assert_allclose(data["poses"][2], data["poses"][1])  # nearest fitted frame (the earlier one)


def test_fake_smplx_fit_writes_an_amass_smplx_layout(tmp_path, fake_models):
    path = str(fake_models["smplx_neutral_npz"])
    model = smplcore.BodyModel(path, model_type="smplx", use_pca=False, flat_hand_mean=True, dtype=np.float64)
    joints = np.asarray(model(body_pose=np.full((3, 63), 0.1)).joints, np.float64)[:, :22]
    np.save(tmp_path / "j.npy", joints)
    out = tmp_path / "sx.npz"
    assert main(["fit", str(tmp_path / "j.npy"), "-o", str(out), "--model-type", "smplx", "--model-path", path]) == 0
    motion = load_motion(out)
    assert motion.model_type == "smplx" and motion.poses.shape == (3, 165)
    with np.load(out) as data:
        assert data["fit_error"].max() < 0.005


def test_the_open_model_is_fitted_in_the_gender_asked_for(tmp_path, sequence):
    """--gender picks the open model's variant too (it has three), as the output's ``gender`` says."""
    male = smplcore.BodyModel(model_type="open", gender="male", dtype=np.float64)
    joints = np.asarray(male(**sequence).joints, np.float64)[:, :22]
    np.save(tmp_path / "j.npy", joints)
    out = tmp_path / "j_male.npz"
    assert main(["fit", str(tmp_path / "j.npy"), "-o", str(out), "--gender", "male"]) == 0
    again = load_motion(out)
    assert again.gender == "male"
    params = again.model_params("open", list(male.skeleton_joint_names))
    fitted = np.asarray(male(**params).joints)[:, :22]
    assert np.linalg.norm(fitted - joints, axis=-1).mean() < 0.005


def test_motion_conversion_reads_the_source_in_the_gender_its_file_names(tmp_path, sequence):
    """A female motion converted to the neutral model: the source mesh is the female one (the file says so),
    whatever --gender asks of the target."""
    from smplcore.motion import Motion, save_motion

    female = smplcore.BodyModel(model_type="open", gender="female", dtype=np.float64)
    neutral = smplcore.BodyModel(model_type="open", dtype=np.float64)
    poses = np.concatenate([sequence["global_orient"], sequence["body_pose"]], 1)
    motion = Motion(poses, sequence["transl"], sequence["betas"][0], 30.0, gender="female", model_type="smpl")
    path = save_motion(motion, tmp_path / "her.npz")
    out = tmp_path / "her_neutral.npz"
    assert main(["fit", str(path), "-o", str(out), "--gender", "neutral"]) == 0
    again = load_motion(out)
    assert again.gender == "neutral"
    names = list(neutral.skeleton_joint_names)
    source = np.asarray(female(**motion.model_params("open", names)).vertices)
    same_params = np.asarray(neutral(**motion.model_params("open", names)).vertices)
    gap = np.linalg.norm(source - same_params, axis=-1).mean()  # the neutral mesh of the same parameters
    fitted = np.asarray(neutral(**again.model_params("open", names)).vertices)
    assert np.linalg.norm(fitted - source, axis=-1).mean() < 0.3 * gap  # the female mesh, not the neutral one


def test_joints_npy_with_joint_weights_and_a_lost_marker(tmp_path, open_model, sequence, capsys):
    """A NaN marker is missing in that frame only (the sequence is fitted); --joint-weights leaves joints out."""
    joints = np.asarray(open_model(**sequence).joints, np.float64)[:, :22]
    joints[1, 20] = np.nan  # the left wrist lost in frame 1
    wrong = joints.copy()
    wrong[:, 21] += 0.3  # the right wrist 30 cm off everywhere: weighted 0 below, so it must not pull
    path = tmp_path / "j22.npy"
    np.save(path, wrong)
    names = ",".join(open_model.joint_names[:22])
    out = tmp_path / "w.npz"
    weights = ",".join(["1"] * 21 + ["0"])
    assert main(["fit", str(path), "-o", str(out), "--joint-names", names, "--joint-weights", weights]) == 0
    with np.load(out) as data:
        assert data["fit_error"].max() < 0.005  # over the joints used: the zero-weight wrist is not counted
    fitted = np.asarray(open_model(**{k: v for k, v in load_motion(out).model_params("open").items()}).joints)
    # unobserved, the wrist goes where the elbow's prior puts it (a few cm off), not to the +30 cm target
    assert np.linalg.norm(fitted[:, 21] - joints[:, 21], axis=-1).max() < 0.15
    with pytest.raises(SystemExit):
        main(["fit", str(path), "-o", str(out), "--joint-names", names, "--joint-weights", "1,-1"])
    assert "expected non-negative numbers" in capsys.readouterr().err
    assert (
        main(["fit", str(path), "-o", str(tmp_path / "x.npz"), "--joint-names", names, "--joint-weights", "1,1"]) == 1
    )
    assert "--joint-weights: 2 weights for the 22 joints" in capsys.readouterr().err
