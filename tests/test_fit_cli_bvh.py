"""``smplcore fit`` on BVH motion capture and on joints in other units: skeleton and units detected and said,
one person (shared betas), the clip's frame rate; centimetre .npy joints converted with a message; bad options
refused before any fit; a real clip when the shared mocap is present."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest

import smplcore
from smplcore.cli import main
from smplcore.export import save_bvh
from smplcore.fit.priors import joint_limits
from smplcore.motion import load_motion

MOCAP = Path("/work/shared/data/mocap")


@pytest.fixture(scope="module")
def open_model():
    return smplcore.BodyModel(model_type="open", dtype=np.float64)


@pytest.fixture(scope="module")
def motion(open_model):
    rng = np.random.default_rng(5)
    frames = 6
    pose = rng.normal(scale=0.15, size=(1, 69)) + np.linspace(0, 0.2, frames)[:, None]
    lo, hi = joint_limits(open_model.joint_names[1:24])  # a body inside the joint limits the fit keeps
    pose = np.clip(pose, lo.reshape(-1) + 0.02, hi.reshape(-1) - 0.02)
    return {
        "body_pose": pose,
        "global_orient": np.tile([[0.1, 0.4, 0.0]], (frames, 1)),
        "transl": np.tile([[0.2, 0.9, -0.3]], (frames, 1)),
        "betas": np.tile(rng.normal(size=(1, 10)), (frames, 1)),
    }


def _bvh_cm(path: Path, model, params) -> Path:
    """The motion as smplcore's exporter writes it, in centimetres, at 60 fps."""
    save_bvh(path, model, params, scale=100.0, fps=60.0, decimals=5)
    return path


def test_bvh_in_centimetres_is_detected_said_and_fitted(tmp_path, open_model, motion, capsys):
    clip = _bvh_cm(tmp_path / "walk.bvh", open_model, motion)
    out = tmp_path / "walk.npz"
    assert main(["fit", str(clip), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "skeleton: smpl" in text and "detected from the joint names" in text
    assert "units: centimetres (detected" in text and "converted to metres" in text
    fitted = load_motion(out)
    assert fitted.num_frames == 6 and fitted.fps == 60.0
    with np.load(out) as data:
        assert data["fit_kind"] == "bvh" and data["fit_error"].max() < 0.005  # metres
        assert data["betas"].ndim == 1  # one person: one shape
    again = open_model(**fitted.model_params("open")).joints[:, :22]
    np.testing.assert_allclose(again, open_model(**motion).joints[:, :22], atol=0.01)


def test_bvh_gz_and_a_folder_of_clips(tmp_path, open_model, motion, capsys):
    folder = tmp_path / "clips"
    folder.mkdir()
    plain = _bvh_cm(tmp_path / "a.bvh", open_model, motion)
    (folder / "a.bvh.gz").write_bytes(gzip.compress(plain.read_bytes()))
    (folder / "b.bvh").write_bytes(plain.read_bytes())
    out = tmp_path / "fits"
    assert main(["fit", str(folder), "-o", str(out), "--no-progress"]) == 0
    assert sorted(p.name for p in out.glob("*.npz")) == ["a.npz", "b.npz"]
    assert "2 fitted, 0 skipped" in capsys.readouterr().out


def test_units_and_skeleton_given(tmp_path, open_model, motion, capsys):
    clip = _bvh_cm(tmp_path / "walk.bvh", open_model, motion)
    out = tmp_path / "walk.npz"
    assert main(["fit", str(clip), "-o", str(out), "--units", "cm", "--skeleton", "smpl"]) == 0
    text = capsys.readouterr().out
    assert "units: centimetres (given)" in text and "skeleton: smpl" not in text  # given: nothing detected
    wrong = tmp_path / "wrong.npz"
    assert main(["fit", str(clip), "-o", str(wrong), "--units", "m", "--skeleton", "smpl"]) == 1  # 100x too large
    assert "skipped" in capsys.readouterr().err


@pytest.mark.parametrize(
    "option,value,message",
    [("--skeleton", "nope", "unknown skeleton 'nope'"), ("--units", "furlongs", "expected one of")],
)
def test_bad_options_exit_2_before_any_fit(tmp_path, open_model, motion, capsys, option, value, message):
    clip = _bvh_cm(tmp_path / "walk.bvh", open_model, motion)
    with pytest.raises(SystemExit) as info:
        main(["fit", str(clip), "-o", str(tmp_path / "x.npz"), option, value])
    assert info.value.code == 2 and message in capsys.readouterr().err


def test_a_bvh_of_an_unknown_skeleton_is_skipped_with_the_reason(tmp_path, capsys):
    path = tmp_path / "robot.bvh"
    header = "HIERARCHY\nROOT base\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation "
    header += "Yrotation\n"
    arm = "JOINT arm\n{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\nEnd Site\n{\nOFFSET 0 1 0\n}\n}\n}\n"
    path.write_text(header + arm + "MOTION\nFrames: 1\nFrame Time: 0.1\n0 0 0 0 0 0 0 0 0\n")
    assert main(["fit", str(path), "-o", str(tmp_path / "robot.npz")]) == 1
    err = capsys.readouterr().err
    assert "no known skeleton has the joints base, arm" in err and "--skeleton" in err


def test_centimetre_joints_npy_are_converted_with_a_message(tmp_path, open_model, motion, capsys):
    joints = open_model(**motion).joints[:, :22] * 100.0
    path = tmp_path / "joints_cm.npy"
    np.save(path, joints)
    out = tmp_path / "fit.npz"
    assert main(["fit", str(path), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "joints: units: centimetres (detected" in text and "--units m" in text
    with np.load(out) as data:
        assert data["fit_error"].max() < 0.005 and abs(data["betas"]).max() < 5  # a person, not betas of 1357
    np.save(tmp_path / "huge.npy", joints * 1000.0)  # 10 km legs: no unit makes a person of them
    assert main(["fit", str(tmp_path / "huge.npy"), "-o", str(tmp_path / "huge.npz")]) == 1
    assert "not a person's in m, cm, mm" in capsys.readouterr().err


def test_keypoint_skeleton_npy_in_millimetres(tmp_path, open_model, motion, capsys):
    from smplcore import keypoints

    h36m, _ = keypoints.convert(open_model(**motion).joints, open_model, "h36m17")
    path = tmp_path / "h36m.npy"
    np.save(path, h36m * 1000.0)
    out = tmp_path / "fit.npz"
    assert main(["fit", str(path), "-o", str(out), "--skeleton", "h36m17"]) == 0
    assert "units: millimetres (detected" in capsys.readouterr().out
    with np.load(out) as data:
        assert data["fit_error"].max() < 0.01


def test_real_clip(tmp_path, capsys):
    path = MOCAP / "cmu_mb_jonathanalderson" / "05_06.bvh.gz"
    if not path.is_file():
        pytest.skip(f"the shared mocap ({path}) is absent")
    out = tmp_path / "05_06.npz"
    assert main(["fit", str(path), "-o", str(out), "--max-iter", "3"]) == 0
    text = capsys.readouterr().out
    assert "skeleton: cmu_mb" in text and "CMU ASF units" in text and "reference pose" in text
    assert load_motion(out).num_frames == 885 and load_motion(out).fps == pytest.approx(120.0, rel=1e-3)
