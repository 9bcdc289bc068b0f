"""``smplcore fit`` never loses work and never ends in a traceback: without threadpoolctl, on a full or
read-only disk, with ``-o`` naming a file, on Ctrl-C, with a bad prior or a FIFO as input, ``--fps nan``."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import smplcore
from smplcore.cli import main
from smplcore.motion import load_motion

TESTS = Path(__file__).resolve().parent
SRC = TESTS.parent / "src"


@pytest.fixture(scope="module")
def joints_inputs(tmp_path_factory):
    """A folder of joints inputs (.npy, 22 named joints of the open model) and their names."""
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    rng = np.random.default_rng(3)
    folder = tmp_path_factory.mktemp("fit_inputs")
    for i in range(8):
        pose = rng.normal(0, 0.1, (12, 69))
        joints = np.asarray(model(body_pose=pose).joints, np.float64)[:, :22]
        np.save(folder / f"clip{i}.npy", joints)
    return folder, ",".join(model.joint_names[:22])


def _child(argv: list[str], prelude: str = "", **kwargs) -> subprocess.Popen:
    code = f"import sys\n{prelude}\nfrom smplcore.cli import main\nsys.exit(main({argv!r}))"
    env = dict(os.environ, PYTHONPATH=str(SRC), OPENBLAS_NUM_THREADS="1")
    return subprocess.Popen(
        [sys.executable, "-W", "ignore", "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=env, **kwargs,
    )  # fmt: skip


def _subset(joints_inputs, tmp_path, count: int) -> tuple[Path, str]:
    folder, names = joints_inputs
    sub = tmp_path / "in"
    sub.mkdir()
    for p in sorted(folder.glob("*.npy"))[:count]:
        (sub / p.name).write_bytes(p.read_bytes())
    return sub, names


def test_fps_nan_is_refused_when_the_arguments_are_parsed(tmp_path, capsys):
    for value in ("nan", "inf", "0", "-30"):
        with pytest.raises(SystemExit) as exit_info:
            main(["fit", str(tmp_path / "x.npy"), "-o", str(tmp_path / "o.npz"), "--fps", value])
        assert exit_info.value.code == 2
        assert f"--fps: expected a finite number > 0, got '{value}'" in capsys.readouterr().err


def test_workers_without_threadpoolctl_keep_every_output(joints_inputs, tmp_path):
    inputs, names = _subset(joints_inputs, tmp_path, 2)
    out = tmp_path / "out"
    argv = ["fit", str(inputs), "-o", str(out), "--joint-names", names, "--workers", "2", "--no-progress"]
    child = _child(argv, prelude="sys.modules['threadpoolctl'] = None  # import threadpoolctl fails")
    stdout, stderr = child.communicate(timeout=600)
    assert child.returncode == 0, stderr
    assert "2 fitted, 0 skipped" in stdout and "Traceback" not in stderr
    assert sorted(p.name for p in out.glob("*.npz")) == ["clip0.npz", "clip1.npz"]
    assert load_motion(out / "clip0.npz").num_frames == 12


def test_output_naming_a_file_where_a_folder_is_needed(joints_inputs, tmp_path, capsys):
    inputs, names = _subset(joints_inputs, tmp_path, 2)
    taken = tmp_path / "taken"
    taken.write_text("not a folder")
    assert main(["fit", str(inputs), "-o", str(taken), "--joint-names", names]) == 2
    err = capsys.readouterr().err
    assert f"-o/--output: {taken} is a file; a folder of inputs needs an output folder" in err
    assert taken.read_text() == "not a folder"
    one = inputs / "clip0.npy"
    (tmp_path / "dir.npz").mkdir()
    assert main(["fit", str(one), "-o", str(tmp_path / "dir.npz"), "--joint-names", names]) == 2
    assert "is a folder; one input writes one .npz file" in capsys.readouterr().err


@contextlib.contextmanager
def _tmpfs(path: Path, options: str):
    path.mkdir()
    result = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(path)], capture_output=True)
    if result.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({result.stderr.decode().strip()})")
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)], capture_output=True)


def test_a_full_disk_stops_the_batch_with_a_message_and_keeps_finished_outputs(joints_inputs, tmp_path, capsys):
    inputs, names = _subset(joints_inputs, tmp_path, 3)
    with _tmpfs(tmp_path / "disk", "size=64k") as disk:
        out = disk / "out"
        out.mkdir()
        (out / "clip0.npz").write_bytes(b"finished earlier")  # an output of an earlier run
        with contextlib.suppress(OSError), open(disk / "filler", "wb") as fh:
            while True:
                fh.write(bytes(4096))
                fh.flush()
        argv = ["fit", str(inputs), "-o", str(out), "--joint-names", names, "--no-progress"]
        assert main(argv) == 1
        text = capsys.readouterr()
        assert "smplcore fit: stopped: cannot write" in text.err and "No space left on device" in text.err
        assert f"cannot write {out / 'fit_manifest.json'}" in text.err
        assert "0 fitted, 1 skipped (bad input), 1 already done" in text.out  # stopped after the first failure
        assert (out / "clip0.npz").read_bytes() == b"finished earlier"
        assert not [p for p in out.iterdir() if p.name != "clip0.npz"]  # no partial files left


def test_a_read_only_output_folder_is_a_message_not_a_traceback(joints_inputs, tmp_path, capsys):
    inputs, names = _subset(joints_inputs, tmp_path, 2)
    with _tmpfs(tmp_path / "ro", "ro,size=64k") as disk:
        assert main(["fit", str(inputs), "-o", str(disk), "--joint-names", names, "--no-progress"]) == 1
        err = capsys.readouterr().err
        assert "stopped: cannot write" in err and "Read-only file system" in err
        assert main(["fit", str(inputs), "-o", str(disk / "sub"), "--joint-names", names]) == 2
        assert "cannot make the folder" in capsys.readouterr().err


def test_ctrl_c_ends_with_a_message_and_status_130_keeping_finished_outputs(joints_inputs, tmp_path):
    inputs, names = joints_inputs
    out = tmp_path / "out"
    argv = ["fit", str(inputs), "-o", str(out), "--joint-names", names, "--workers", "2", "--no-progress"]
    child = _child(argv, start_new_session=True)
    deadline = time.monotonic() + 600
    while not list(out.glob("clip*.npz")) and child.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert child.poll() is None, "the batch ended before Ctrl-C could be sent"
    os.killpg(child.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the parent and its workers
    stdout, stderr = child.communicate(timeout=120)
    assert child.returncode == 130, stderr
    assert "interrupted;" in stderr and "run the same command again" in stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr
    written = sorted(out.glob("clip*.npz"))
    assert 1 <= len(written) < 8
    for path in written:
        assert load_motion(path).num_frames == 12
    manifest = json.loads((out / "fit_manifest.json").read_text())
    assert {e["output"] for e in manifest["entries"] if e["status"] == "done"} == {str(p) for p in written}
    assert not list(out.glob(".*smplcore-tmp"))


def test_a_bad_prior_file_is_one_clear_error_and_a_fifo_input_is_refused(joints_inputs, tmp_path, capsys):
    from aux_fuzz import nested_pickle

    inputs, names = _subset(joints_inputs, tmp_path, 1)
    gmm = tmp_path / "gmm_08.pkl"
    gmm.write_bytes(nested_pickle())
    # the nesting check refuses it (the 380-byte file describes 2**37 list entries: walking them would not end)
    assert main(["fit", str(inputs), "-o", str(tmp_path / "o"), "--joint-names", names, "--gmm", str(gmm)]) == 2
    assert f"{gmm}: holds nested lists" in capsys.readouterr().err
    fifo = tmp_path / "joints.npy"
    os.mkfifo(fifo)
    assert main(["fit", str(fifo), "-o", str(tmp_path / "o.npz"), "--joint-names", names]) == 2
    assert "is not a regular file (a FIFO)" in capsys.readouterr().err


def test_the_fit_command_survives_crafted_inputs_and_prior_files():
    """tests/aux_fuzz.py --fit-cli: crafted INPUT, --gmm and --vposer files (truncated, wrong dtype, huge shapes,
    nested, object arrays, zip bombs, code-running pickles, FIFOs, folders, symlink loops, /dev/zero): each
    ends with status 1 or 2 and a message naming the file; no hang, no traceback, nothing run."""
    env = dict(os.environ, PYTHONPATH=str(SRC), OPENBLAS_NUM_THREADS="1")
    command = [sys.executable, "-W", "ignore", str(TESTS / "aux_fuzz.py"), "--fit-cli"]
    result = subprocess.run(command, capture_output=True, text=True, env=env, timeout=900)
    assert result.returncode == 0, result.stderr[-2000:]
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert not report["executed"] and report["inputs"] >= 100, report
    counts = report["counts"]
    assert counts["raw"] == counts["hang"] == counts["unclear"] == 0, report["failures"]
    assert counts["clean"] == 1 and counts["clear"] == report["inputs"] - 1, counts
