"""``smplcore process`` on a full disk: a clean stop (exit 3), a valid manifest, a resume once there is room.

The disk is a small tmpfs when this runs as root and mounting works; otherwise a file-size limit
(RLIMIT_FSIZE, which gives EFBIG) set in the subprocess stands in for it.
"""

from __future__ import annotations

import contextlib
import json
import os
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from smplcore.io.locate import OPEN_MODEL_PATH
from smplcore.motion import EXIT_DISK_FULL
from smplcore.motion.synthetic import write_tree

pytestmark = pytest.mark.skipif(not OPEN_MODEL_PATH.exists(), reason="the open model is not built")

SEQUENCES = [(f"S/seq{i}_poses.npz", 10, 30.0, "female") for i in range(6)]  # outputs of about 2 MB each


def _mount_tmpfs(path: Path, size: str) -> bool:
    path.mkdir(parents=True, exist_ok=True)
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        return False
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)], capture_output=True)
    return done.returncode == 0


@pytest.fixture
def small_disk(tmp_path):
    """(folder, limit): a 3 MB tmpfs (limit None), or a plain folder and a file-size limit for the subprocess."""
    disk = tmp_path / "disk"
    mounted = _mount_tmpfs(disk, "3m")
    try:
        yield disk, (None if mounted else 400_000)
    finally:
        if mounted:
            subprocess.run(["umount", "-l", str(disk)], check=False)


def _run(args: list[str], fsize: int | None = None) -> subprocess.CompletedProcess:
    def limit() -> None:
        if fsize is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))

    cmd = [sys.executable, "-m", "smplcore.cli", "process", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120, preexec_fn=limit)


def _grow(disk: Path) -> None:
    subprocess.run(["mount", "-o", "remount,size=40m", str(disk)], check=True)


def test_full_disk_stops_cleanly_keeps_outputs_and_resumes(small_disk, tmp_path):
    disk, fsize = small_disk
    src, out = tmp_path / "in", disk / "out"
    write_tree(src, SEQUENCES, seed=3)
    args = [str(src), str(out), "--vertices", "--workers", "2", "--quiet"]
    first = _run(args, fsize)
    assert first.returncode == EXIT_DISK_FULL, first.stderr
    assert "Traceback" not in first.stderr
    reason = [line for line in first.stderr.splitlines() if line.startswith("smplcore process: stopped: disk full")]
    assert len(reason) == 1 and ("ENOSPC" in reason[0] or "EFBIG" in reason[0]) and "rerun" in reason[0]
    assert "not done" in first.stdout and "files:" in first.stdout  # the summary is printed

    manifest = json.loads((out / "manifest.json").read_text())  # valid JSON, final status
    assert manifest["status"] == "stopped"
    status = {e["input"]: e["status"] for e in manifest["files"]}
    assert sorted(status) == sorted(rel for rel, *_ in SEQUENCES)  # every file is accounted for
    assert set(status.values()) <= {"done", "not_done"} and "not_done" in status.values()
    done = [rel for rel, s in status.items() if s == "done"]
    assert manifest["totals"]["done"] == len(done) and manifest["totals"]["not_done"] == len(SEQUENCES) - len(done)
    if fsize is None:
        assert done, "a 3 MB disk holds at least one output"
    for rel, *_ in SEQUENCES:  # finished outputs are complete; the others are not there at all
        path = out / rel
        assert path.exists() == (rel in done)
        if path.exists():
            with np.load(path) as f:
                assert f["vertices"].shape[0] == 10
    assert not [p for p in out.rglob("*") if p.name.startswith(".")], "temporaries, lock or reserve left behind"

    if fsize is None:
        _grow(disk)
    again = _run(args)  # room again: the rerun resumes
    assert again.returncode == 0, again.stderr
    assert f"{len(SEQUENCES) - len(done)} processed, {len(done)} already done" in again.stdout
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "finished"
    assert {e["status"] for e in manifest["files"]} <= {"done", "exists"}


def test_a_disk_full_at_start_is_one_clear_line(small_disk, tmp_path):
    disk, fsize = small_disk
    src = tmp_path / "in"
    write_tree(src, SEQUENCES[:2], seed=3)
    if fsize is None:  # fill the tmpfs
        with open(disk / "filler", "wb") as fh, contextlib.suppress(OSError):
            while True:
                fh.write(bytes(1 << 16))
                fh.flush()
        fsize_at_start = None
    else:
        fsize_at_start = 1  # not even the lock file's pid fits
    done = _run([str(src), str(disk / "out"), "--workers", "0", "--quiet"], fsize_at_start)
    assert done.returncode == EXIT_DISK_FULL
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith("smplcore process: ") and "disk full" in lines[0] and "free some space" in lines[0]
    assert done.stdout == ""


@pytest.mark.parametrize("code", ["EDQUOT", "ENOSPC", "EFBIG"])
def test_every_no_room_error_stops_the_run_in_python(tmp_path, monkeypatch, code):
    """In-process: the second output does not fit; ProcessFailed (or, with check=False, the summary) says so."""
    import errno

    from smplcore.motion import ProcessFailed, process_tree
    from smplcore.motion.process import task as task_module

    write_tree(tmp_path / "in", SEQUENCES[:4], seed=4)
    real = task_module.atomic_write
    calls = []

    def full_after_one(path, write):
        calls.append(path)
        if len(calls) > 1:
            raise OSError(getattr(errno, code), os.strerror(getattr(errno, code)))
        real(path, write)

    monkeypatch.setattr(task_module, "atomic_write", full_after_one)
    with pytest.raises(ProcessFailed, match=f"stopped: disk full writing .*{code}") as info:
        process_tree(tmp_path / "in", tmp_path / "out", workers=0, progress=False)
    summary = info.value.summary
    assert (summary.done, summary.not_done, summary.skipped, summary.exit_code) == (1, 3, [], EXIT_DISK_FULL)
    assert len(calls) == 2  # no file started after the disk filled
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert manifest["status"] == "stopped" and manifest["totals"]["not_done"] == 3
    monkeypatch.setattr(task_module, "atomic_write", real)
    again = process_tree(tmp_path / "in", tmp_path / "out", workers=0, progress=False)
    assert (again.done, again.existing, again.exit_code) == (3, 1, 0)
