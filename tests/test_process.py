"""``smplcore process``: AMASS-style tree to joints / meshes; bad files, resume, kill-and-resume."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import fakes
from smplcore import BodyModel
from smplcore.cli import main
from smplcore.io.locate import OPEN_MODEL_PATH
from smplcore.motion import ProcessOptions, load_motion, options_from_recipe, process_tree
from smplcore.motion.process import LOCK_NAME, TMP_SUFFIX, ProcessError
from smplcore.motion.process.manifest import _locked
from smplcore.motion.synthetic import random_arrays, write_sequence, write_tree

GOOD = [  # (relative path, frames, fps, gender)
    ("CMU/01/01_01_poses.npz", 240, 120.0, "female"),
    ("CMU/01/01_02_poses.npz", 90, 60.0, "male"),
    ("KIT/3/walk_poses.npz", 100, 100.0, "neutral"),
]
BAD = {
    "Bad/truncated_poses.npz": ("truncated or corrupt", None),
    "Bad/mismatch_poses.npz": ("trans", "trans"),
    "Bad/nan_poses.npz": ("NaN", "poses"),
}


def _load(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as f:
        return {k: f[k] for k in f.files}


@pytest.fixture(scope="module")
def models(tmp_path_factory) -> Path:
    """SMPL+H models in both layouts: smplx-style (female) and AMASS-style (male, neutral)."""
    root = tmp_path_factory.mktemp("body_models")
    fakes.write_smplh(root / "smplh", "female", "npz", amass=True)
    fakes.write_smplh(root / "smplh", "male", "npz", amass=True, official_name=True)
    fakes.write_smplh(root / "smplh", "neutral", "npz", amass=True, official_name=True)
    return root


def _model_file(models: Path, gender: str) -> Path:
    return models / "smplh" / ("SMPLH_FEMALE.npz" if gender == "female" else f"{gender}/model.npz")


@pytest.fixture(scope="module")
def tree(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("amass")
    write_tree(root, GOOD)
    np.savez(root / "CMU" / "01" / "shape.npz", betas=np.zeros(16), gender="female")  # AMASS: not a motion
    truncated = write_sequence(root / "Bad/truncated_poses.npz", 120, 120.0, "smplh", "female", seed=7)
    data = truncated.read_bytes()
    truncated.write_bytes(data[: len(data) * 2 // 3])
    arrays = random_arrays(50, 60.0, "smplh", "male", seed=8)
    arrays["trans"] = arrays["trans"][:-4]
    np.savez(root / "Bad/mismatch_poses.npz", **arrays)
    arrays = random_arrays(50, 60.0, "smplh", "female", seed=9)
    arrays["poses"][17, 40] = np.nan
    np.savez(root / "Bad/nan_poses.npz", **arrays)
    return root


@pytest.fixture(scope="module")
def first_run(tree, models, tmp_path_factory):
    out = tmp_path_factory.mktemp("out")
    options = ProcessOptions(model_path=str(models), fps=20.0, backend="numpy")
    summary = process_tree(tree, out, options, workers=0, progress=False, check=False)
    return out, options, summary


def _direct_joints(models: Path, rel: str, tree: Path, fps: float = 20.0) -> tuple[np.ndarray, object]:
    motion = load_motion(tree / rel).resample(fps)
    model = BodyModel(_model_file(models, motion.gender), num_betas=16, use_pca=False, flat_hand_mean=True)
    params = motion.model_params("smplh")
    return model(return_verts=False, **params).joints[:, :52], motion


def test_outputs_match_a_direct_forward_frame_by_frame(first_run, tree, models):
    out, _, summary = first_run
    assert summary.files == 6 and summary.done == 3 and summary.existing == 0
    assert summary.frames == sum(round(f * 20 / fps) for _, f, fps, _ in GOOD)  # 40 + 30 + 20
    for rel, _, fps, gender in GOOD:
        got = _load(out / rel)
        expected, motion = _direct_joints(models, rel, tree)
        assert got["joints"].shape == (motion.num_frames, 52, 3) and got["joints"].dtype == np.float32
        np.testing.assert_allclose(got["joints"], expected, atol=2e-5)
        assert float(got["fps"]) == 20.0 and float(got["source_fps"]) == fps
        np.testing.assert_allclose(got["source_frame"], np.arange(motion.num_frames) * fps / 20.0)
        assert str(got["gender"]) == gender and str(got["source"]) == rel
        assert list(got["joint_names"][:3]) == ["pelvis", "left_hip", "right_hip"]
    assert not (out / "CMU/01/shape.npz").exists()


def test_bad_files_are_reported_skipped_and_counted(first_run, tree):
    out, _, summary = first_run
    assert summary.exit_code == 1
    skipped = dict(summary.skipped)
    assert sorted(skipped) == sorted(BAD)
    for rel, (words, key) in BAD.items():
        assert words in skipped[rel]
        assert str(tree / rel) in skipped[rel]  # the path...
        if key:
            assert f"[key '{key}']" in skipped[rel]  # ...and the key at fault
        assert not (out / rel).exists()
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "finished"
    assert manifest["totals"]["done"] == 3 and manifest["totals"]["skipped"] == 3
    status = {e["input"]: e["status"] for e in manifest["files"]}
    assert status == {**{g[0]: "done" for g in GOOD}, **{b: "skipped" for b in BAD}}
    assert all(e["reason"] for e in manifest["files"] if e["status"] == "skipped")


def test_rerun_skips_everything_done(first_run, tree):
    out, options, _ = first_run
    stamps = {rel: (out / rel).stat().st_mtime_ns for rel, *_ in GOOD}
    stale = out / "CMU" / f".01_01_poses.npz.123-abcdef01{TMP_SUFFIX}"  # left by a killed run
    stale.write_bytes(b"partial")
    again = process_tree(tree, out, options, workers=0, progress=False, check=False)
    assert (again.done, again.existing, len(again.skipped)) == (0, 3, 3) and again.exit_code == 1
    assert {rel: (out / rel).stat().st_mtime_ns for rel in stamps} == stamps
    assert not stale.exists()
    manifest = json.loads((out / "manifest.json").read_text())
    entries = {e["input"]: e for e in manifest["files"]}
    assert entries[GOOD[0][0]]["status"] == "exists" and entries[GOOD[0][0]]["frames"] == 40


def test_rerun_with_other_settings_is_refused(first_run, tree):
    out, options, _ = first_run
    with pytest.raises(ProcessError, match="other settings"):
        process_tree(
            tree, out, ProcessOptions(model_path=options.model_path, fps=30.0), workers=0, progress=False, check=False
        )


def test_locked_output_folder_is_refused(tree, models, tmp_path):
    with _locked(tmp_path):
        with pytest.raises(ProcessError, match="another"):
            process_tree(tree, tmp_path, ProcessOptions(model_path=str(models)), workers=0, progress=False, check=False)
        assert (tmp_path / LOCK_NAME).read_text() == f"{os.getpid()}\n"  # the holder's pid
    assert not (tmp_path / LOCK_NAME).exists()  # removed when the run ends


def test_worker_processes_give_the_same_outputs(first_run, tree, models, tmp_path):
    """Two spawned workers agree with the in-process run, bit for bit."""
    out, options, _ = first_run
    summary = process_tree(tree, tmp_path, options, workers=2, progress=False, check=False)
    assert (summary.done, len(summary.skipped), summary.workers) == (3, 3, 2)
    for rel, *_ in GOOD:
        np.testing.assert_array_equal(_load(tmp_path / rel)["joints"], _load(out / rel)["joints"])


def test_torch_backend_agrees(first_run, tree, models, tmp_path):
    pytest.importorskip("torch")
    out, options, _ = first_run
    summary = process_tree(tree, tmp_path, replace(options, backend="torch"), workers=0, progress=False, check=False)
    assert summary.done == 3
    for rel, *_ in GOOD:
        np.testing.assert_allclose(_load(tmp_path / rel)["joints"], _load(out / rel)["joints"], atol=2e-5)


def test_cli(first_run, tree, models, tmp_path, capsys):
    argv = [
        "process",
        str(tree),
        str(tmp_path),
        "--model-path",
        str(models),
        "--fps",
        "20",
        "--workers",
        "0",
        "--backend",
        "numpy",
        "--quiet",
        "--num-joints",
        "22",
        "--dtype",
        "float16",
        "--axes",
        "x,-z,y",
    ]
    assert main(argv) == 1
    text = capsys.readouterr()
    assert "6 files: 3 processed, 0 already done, 3 skipped" in text.out and "frames/s" in text.out
    assert "Bad/nan_poses.npz" in text.err
    out, _, _ = first_run
    for rel, *_ in GOOD:
        got, ref = _load(tmp_path / rel)["joints"], _load(out / rel)["joints"]
        assert got.shape[1:] == (22, 3) and got.dtype == np.float16
        np.testing.assert_allclose(got, ref[:, :22][..., [0, 2, 1]] * [1, -1, 1], atol=5e-3)
    assert main(argv) == 1  # resumed: the bad files are still there
    assert "0 processed, 3 already done" in capsys.readouterr().out
    assert main(argv[:-2]) == 2  # other settings
    assert "other settings" in capsys.readouterr().err


def test_humanml3d_recipe_matches_its_extraction(models, tmp_path):
    """``--recipe humanml3d`` equals HumanML3D's raw_pose_processing, reimplemented here directly."""
    src = tmp_path / "amass_data"
    write_tree(
        src,
        [
            ("ACCAD/a_poses.npz", 130, 120.0, "male"),
            ("BMLrub/b_poses.npz", 90, 59.94, "neutral"),
            ("KIT/c_poses.npz", 77, 100.0, "female"),
        ],
        seed=5,
    )
    out = tmp_path / "pose_data"
    assert (
        main(
            [
                "process",
                str(src),
                str(out),
                "--model-path",
                str(models),
                "--recipe",
                "humanml3d",
                "--workers",
                "0",
                "--backend",
                "numpy",
                "--quiet",
            ]
        )
        == 0
    )
    trans_matrix = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
    bms = {}
    for rel in ("ACCAD/a_poses.npz", "BMLrub/b_poses.npz", "KIT/c_poses.npz"):
        bdata = np.load(src / rel)
        fps = bdata["mocap_framerate"]
        down_sample = int(fps / 20)
        gender = "male" if str(bdata["gender"]) == "male" else "female"
        if gender not in bms:
            bms[gender] = BodyModel(
                models / "smplh" / ("male/model.npz" if gender == "male" else "SMPLH_FEMALE.npz"),
                num_betas=10,
                use_pca=False,
                flat_hand_mean=True,
            )
        poses, trans = bdata["poses"][::down_sample], bdata["trans"][::down_sample]
        body = bms[gender](
            return_verts=False,
            global_orient=poses[:, :3],
            body_pose=poses[:, 3:66],
            left_hand_pose=poses[:, 66:111],
            right_hand_pose=poses[:, 111:],
            betas=np.repeat(bdata["betas"][:10][None], len(trans), axis=0),
            transl=trans,
        )
        expected = np.dot(body.joints[:, :52], trans_matrix)
        got = np.load(out / rel.replace(".npz", ".npy"))
        assert got.shape == expected.shape == (len(poses), 52, 3)
        np.testing.assert_allclose(got, expected, atol=2e-5)
        np.testing.assert_allclose(got[:, :22], expected[:, :22], atol=2e-5)  # HumanML3D's 22 joints
    # The 22-joint arrays directly:
    out22 = tmp_path / "joints22"
    options = options_from_recipe("humanml3d", model_path=str(models), num_joints=22, backend="numpy")
    assert process_tree(src, out22, options, workers=0, progress=False, check=False).exit_code == 0
    np.testing.assert_array_equal(np.load(out22 / "KIT/c_poses.npy"), np.load(out / "KIT/c_poses.npy")[:, :22])


def test_smplx_sequences(tmp_path):
    fakes.write_smplx(tmp_path / "models" / "smplx", "male", "npz", "1.0")
    seq = write_sequence(tmp_path / "in" / "x_stageii.npz", 25, 120.0, "smplx", "male")
    summary = process_tree(
        tmp_path / "in",
        tmp_path / "out",
        ProcessOptions(model_path=str(tmp_path / "models"), backend="numpy", extra_joints=True),
        workers=0,
        progress=False,
    )
    assert summary.exit_code == 0
    got = _load(tmp_path / "out" / "x_stageii.npz")
    model = BodyModel(tmp_path / "models", "smplx", gender="male", ext="npz", use_pca=False, flat_hand_mean=True)
    params = load_motion(seq).model_params("smplx")
    params["betas"] = params["betas"][:, :10]
    np.testing.assert_allclose(got["joints"], model(return_verts=False, **params).joints, atol=2e-5)
    assert str(got["model_type"]) == "smplx" and got["joints"].shape[1] == len(model.joint_names)
    # Skeleton joints only (the default): the shorter path gives the same 55 joints.
    summary = process_tree(
        tmp_path / "in",
        tmp_path / "skeleton",
        ProcessOptions(model_path=str(tmp_path / "models"), backend="numpy"),
        workers=0,
        progress=False,
    )
    assert summary.exit_code == 0
    skeleton = _load(tmp_path / "skeleton" / "x_stageii.npz")["joints"]
    assert skeleton.shape == (25, 55, 3)
    np.testing.assert_allclose(skeleton, got["joints"][:, :55], atol=1e-5)


@pytest.mark.skipif(not OPEN_MODEL_PATH.exists(), reason=f"the open model is not built yet ({OPEN_MODEL_PATH})")
def test_open_model_vertices(tree, tmp_path):
    options = ProcessOptions(
        vertices=True, dtype="float16", fps=30.0, resample="nearest", backend="numpy", num_betas=10
    )
    summary = process_tree(tree, tmp_path, options, workers=0, progress=False, exclude=["Bad/*", "shape.npz"])
    assert summary.exit_code == 0 and summary.done == 3
    rel = GOOD[1][0]
    got = _load(tmp_path / rel)
    motion = load_motion(tree / rel).resample(30.0, "nearest")
    model = BodyModel(model_type="open", gender=motion.gender)  # the motion's gender picks the open model's variant
    params = motion.model_params("open")
    params["betas"] = params["betas"][:, : model.num_betas]
    expected = model(return_verts=True, **params)
    assert got["vertices"].dtype == np.float16 and got["vertices"].shape == expected.vertices.shape
    np.testing.assert_allclose(got["vertices"].astype(np.float32), expected.vertices, atol=4e-3)
    np.testing.assert_allclose(got["joints"].astype(np.float32), expected.joints[:, :24], atol=4e-3)
    np.testing.assert_array_equal(got["faces"], model.faces)


# ------------------------------------------------------------------------------------------------
# Kill and resume


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "smplcore.cli", "process", *args]


def _outputs(out: Path) -> list[Path]:
    return sorted(p for p in out.rglob("*.npz"))


def test_kill_and_resume(models, tmp_path):
    """SIGKILL a run mid-way: no partial output; the rerun completes and equals an uninterrupted run."""
    src, out, ref = tmp_path / "in", tmp_path / "out", tmp_path / "ref"
    sequences = [(f"S{i // 4}/seq{i:02d}_poses.npz", 1500, 120.0, "female") for i in range(16)]
    write_tree(src, sequences, seed=11)
    args = [
        str(src),
        str(out),
        "--model-path",
        str(models / "smplh" / "SMPLH_FEMALE.npz"),
        "--workers",
        "2",
        "--backend",
        "numpy",
        "--quiet",
    ]
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        _cli(*args), env=env, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    deadline = time.monotonic() + 60
    while not _outputs(out) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate()
    assert proc.returncode == -signal.SIGKILL, "the run ended before it could be killed"
    at_kill = len(_outputs(out))
    assert 0 < at_kill < len(sequences), f"{at_kill} outputs when killed: not mid-way"
    # The orphaned workers notice that their parent died and exit by themselves.
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline:
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            break
        time.sleep(0.1)
    else:
        os.killpg(proc.pid, signal.SIGKILL)
        pytest.fail("worker processes outlived their killed parent")
    # Whatever is there under an output name is complete.
    for path in _outputs(out):
        assert _load(path)["joints"].shape == (1500, 52, 3)
    manifest = json.loads((out / "manifest.json").read_text())  # written atomically: valid JSON
    assert manifest["status"] == "running"

    rerun = subprocess.run(_cli(*args), env=env, capture_output=True, text=True, timeout=120)
    assert rerun.returncode == 0, rerun.stderr
    assert "already done" in rerun.stdout
    assert not list(out.rglob(f"*{TMP_SUFFIX}")), "temporary files left behind"
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "finished" and manifest["totals"]["exists"] >= at_kill
    assert manifest["totals"]["done"] + manifest["totals"]["exists"] == len(sequences)

    options = ProcessOptions(model_path=str(models / "smplh" / "SMPLH_FEMALE.npz"), backend="numpy")
    assert process_tree(src, ref, options, workers=0, progress=False, check=False).exit_code == 0
    for rel, *_ in sequences:
        got, expected = _load(out / rel), _load(ref / rel)
        assert sorted(got) == sorted(expected)
        for key in expected:
            np.testing.assert_array_equal(got[key], expected[key], err_msg=f"{rel}: {key}")
