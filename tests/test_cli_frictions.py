"""A newcomer's frictions on the command line (issue 31, items 6 and 7): progress options spelled either way,
a clean Ctrl-C, skip messages naming the path typed, warnings as one line."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from smplcore.cli import build_parser
from smplcore.motion.synthetic import write_sequence

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    "command",
    [
        ["process", "in", "out"],
        ["export", "walk.npz", "-o", "walk.glb"],
        ["fit", "op", "-o", "fit.npz"],
        ["render", "walk.npz", "-o", "walk.gif"],
    ],
)
@pytest.mark.parametrize("flag", ["--quiet", "--no-progress"])
def test_every_command_with_a_progress_bar_takes_both_spellings(command, flag):
    args = build_parser().parse_args([*command, flag])
    assert getattr(args, "quiet", None) is True or getattr(args, "no_progress", None) is True


def test_ctrl_c_of_a_pool_run_prints_only_the_clean_message(tmp_path):
    """SIGINT to the whole process group (a terminal's Ctrl-C) of ``process --vertices --workers 2`` while files
    are still queued: exit 130 and the one-line message, no ``InvalidStateError: CANCELLED`` from the pool's
    thread (cancelled futures of a pool its workers then leave; it came in about every other run)."""
    for i in range(10):
        write_sequence(tmp_path / "in" / f"s{i:02d}_poses.npz", 300, fps=30.0, model_type="smplh")
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"), PYTHONUNBUFFERED="1")
    for trial in range(3):
        out = tmp_path / f"out{trial}"
        cmd = [sys.executable, "-m", "smplcore.cli", "process", str(tmp_path / "in"), str(out), "--vertices",
               "--workers", "2", "--no-progress"]  # fmt: skip
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                                start_new_session=True)  # fmt: skip
        deadline = time.monotonic() + 120
        while len(list(out.rglob("*.npz"))) < 1 + trial and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.05)
        os.killpg(proc.pid, signal.SIGINT)
        _, stderr = proc.communicate(timeout=120)
        assert proc.returncode == 130, stderr
        assert stderr.strip().endswith("interrupted; finished outputs are kept, rerun to resume"), stderr
        assert "Error" not in stderr and "Traceback" not in stderr, stderr


def test_a_skipped_input_is_named_as_typed_not_by_its_symlink_target(tmp_path, capsys):
    from smplcore.cli import main

    real = tmp_path / "data" / "real_walk.npz"
    real.parent.mkdir()
    np.savez(real, poses=np.zeros((3, 5)))  # not a motion: skipped
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "walk.npz").symlink_to(real)
    os.chdir(tmp_path)
    status = main(["fit", "in", "-o", "fits", "--no-progress"])
    err = capsys.readouterr().err
    assert status == 1 and "skipped in/walk.npz:" in err and "real_walk" not in err.split(":")[0], err


def test_process_names_a_skipped_symlink_as_typed(tmp_path, capsys):
    from smplcore.cli import main

    real = tmp_path / "data" / "real_walk.npz"
    real.parent.mkdir()
    np.savez(real, poses=np.zeros((3, 5)))  # not a motion: skipped
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "walk_poses.npz").symlink_to(real)
    os.chdir(tmp_path)
    status = main(["process", "in", "out", "--no-progress"])
    captured = capsys.readouterr()
    assert status == 1 and "skipped in/walk_poses.npz:" in captured.err, captured
    assert "real_walk" not in captured.err + captured.out, captured


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_viewer_keypoints_show_through_a_translucent_first_body(tmp_path):
    pytest.importorskip("viser", reason="smplcore view needs the view extra")
    from smplcore.view import Viewer
    from smplcore.view.sources import Source

    np.save(tmp_path / "target.npy", np.zeros((1, 5, 3)))  # inside the body, at the pelvis
    two = [Source(label="a"), Source(label="b")]  # two open models at rest
    with Viewer(two, keypoints=tmp_path / "target.npy", port=_free_port()) as v:
        assert v._nodes[0]["mesh"].opacity is not None and v._nodes[0]["mesh"].opacity < 1.0
        assert v._nodes[1]["mesh"].opacity is None  # the other body stays opaque
        v.set_overlays(skeleton=False)
        assert v._nodes[0]["mesh"].opacity is not None and v._nodes[0]["mesh"].opacity < 1.0
    with Viewer([], port=_free_port()) as v:
        assert v._nodes[0]["mesh"].opacity is None  # no keypoints: opaque


def test_view_says_1_body(monkeypatch, capsys):
    pytest.importorskip("viser", reason="smplcore view needs the view extra")
    import types

    import smplcore.view.cli
    from smplcore.cli import main

    def ctrl_c(seconds: float) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(smplcore.view.cli, "time", types.SimpleNamespace(sleep=ctrl_c))
    assert main(["view", "--port", str(_free_port())]) == 0
    assert "serving 1 body at http://" in capsys.readouterr().out


def test_render_prints_a_shape_space_warning_as_one_line(tmp_path, capsys, monkeypatch):
    pytest.importorskip("imageio_ffmpeg", reason="video needs the view extra")
    import smplcore.motion.sequence

    monkeypatch.setattr(smplcore.motion.sequence, "_warned_shape_space", set())  # said once per process
    from smplcore.cli import main
    from smplcore.motion import Motion, save_motion

    motion = Motion(np.zeros((2, 72)), np.zeros((2, 3)), np.ones(10), 30.0, model_type="smpl")  # SMPL's betas
    path = save_motion(motion, tmp_path / "walk.npz")
    try:
        status = main(["render", str(path), "-o", str(tmp_path / "walk.gif"), "--size", "64x48", "--no-progress"])
    except RuntimeError as exc:  # pragma: no cover - no offscreen OpenGL here
        pytest.skip(str(exc))
    err = capsys.readouterr().err
    assert status == 0, err
    lines = [line for line in err.splitlines() if "betas" in line]
    assert len(lines) == 1 and lines[0].startswith("smplcore render: warning: betas:"), err
    assert "bodies.py" not in err and "warn(" not in err, err
