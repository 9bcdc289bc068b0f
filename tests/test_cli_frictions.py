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
