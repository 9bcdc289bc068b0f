"""``process_tree`` from scripts and the shell: the main-module guard, failures a script cannot miss, resume
after a run that wrote nothing, the lock file, the size warning, Ctrl-C."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from smplcore.io.locate import OPEN_MODEL_PATH
from smplcore.motion import OutputSizeWarning, ProcessError, ProcessFailed, ProcessOptions, process_tree
from smplcore.motion.process import LOCK_NAME
from smplcore.motion.process.preflight import _guarded, estimate_output_bytes
from smplcore.motion.process.task import find_inputs
from smplcore.motion.synthetic import write_sequence, write_tree

pytestmark = pytest.mark.skipif(not OPEN_MODEL_PATH.exists(), reason="the open model is not built")

SEQUENCES = [("a/s1_poses.npz", 60, 60.0, "male"), ("a/s2_poses.npz", 45, 60.0, "female")]


def _script(folder: Path, body: str) -> subprocess.CompletedProcess:
    (folder / "job.py").write_text(textwrap.dedent(body))
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    return subprocess.run([sys.executable, "job.py"], cwd=folder, capture_output=True, text=True, timeout=120, env=env)


def test_a_script_without_the_main_guard_is_refused_with_the_fix(tmp_path):
    write_tree(tmp_path / "amass", SEQUENCES)
    done = _script(
        tmp_path,
        """
        from smplcore.motion import ProcessOptions, process_tree

        summary = process_tree("amass/", "joints/", ProcessOptions(fps=20.0), workers=2)
        print("still running")
        """,
    )
    assert done.returncode == 1 and "still running" not in done.stdout
    last = done.stderr.strip().splitlines()[-1]
    assert "ProcessError" in last and "job.py, line 4" in last and 'if __name__ == "__main__":' in last
    assert "workers=0" in last
    assert not (tmp_path / "joints").exists()  # refused before anything started


def test_a_worker_reimporting_an_unguarded_script_says_so_and_the_script_fails(tmp_path):
    """The worker-side check, should the script's top level escape the parent's check."""
    write_tree(tmp_path / "amass", SEQUENCES)
    done = _script(
        tmp_path,
        """
        import smplcore.motion.process.preflight as preflight
        from smplcore.motion import ProcessOptions, process_tree

        preflight.check_main_guard = lambda: None  # as if the parent could not see the script's top level
        process_tree("amass/", "joints/", ProcessOptions(fps=20.0), workers=2, progress=False)
        print("finished")
        """,
    )
    assert done.returncode == 1 and "finished" not in done.stdout
    assert "this worker process was importing its parent's main script" in done.stderr  # from the workers
    assert "ProcessFailed: 2 files: 0 processed, 0 already done, 2 skipped" in done.stderr  # from the script
    assert not (tmp_path / "joints" / LOCK_NAME).exists()


def test_a_script_read_from_stdin_is_refused_with_workers(tmp_path):
    """Workers cannot import a main script that is not a file: said at once, not as dead workers."""
    write_tree(tmp_path / "amass", SEQUENCES)
    code = 'from smplcore.motion import process_tree\nprocess_tree("amass", "joints", workers=2)\n'
    done = subprocess.run([sys.executable, "-"], input=code, cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert done.returncode == 1
    assert "the main script '<stdin>' is not a file" in done.stderr and "workers=0" in done.stderr
    assert "worker process died" not in done.stderr


def test_the_guarded_script_of_the_docs_runs_with_workers(tmp_path):
    write_tree(tmp_path / "amass", SEQUENCES)
    done = _script(
        tmp_path,
        """
        from smplcore.motion import ProcessOptions, process_tree

        if __name__ == "__main__":
            summary = process_tree("amass/", "joints/", ProcessOptions(fps=20.0), workers=2, progress=False)
            print(summary.done, summary.exit_code)
        """,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["2", "0"]
    assert (tmp_path / "joints/a/s1_poses.npz").exists() and not (tmp_path / "joints" / LOCK_NAME).exists()


def test_guard_detection_reads_the_script_structure():
    import ast

    tree = ast.parse(
        textwrap.dedent(
            """
            import x
            run()
            if __name__ == "__main__":
                try:
                    run()
                finally:
                    pass
            if "__main__" == __name__:
                run()
            if __name__ == "__main__":
                pass
            else:
                run()
            """
        )
    ).body
    assert [_guarded(tree, line) for line in (3, 6, 10, 14)] == [False, True, True, False]


def test_failed_files_raise_unless_check_is_false(tmp_path):
    write_tree(tmp_path / "in", SEQUENCES[:1])
    (tmp_path / "in" / "broken_poses.npz").write_bytes(b"PK\x03\x04 not a zip")
    with pytest.raises(ProcessFailed, match="1 skipped") as info:
        process_tree(tmp_path / "in", tmp_path / "out", workers=0, progress=False)
    summary = info.value.summary
    assert (summary.done, len(summary.skipped), summary.exit_code) == (1, 1, 1)
    assert json.loads((tmp_path / "out" / "manifest.json").read_text())["status"] == "finished"
    again = process_tree(tmp_path / "in", tmp_path / "out", workers=0, progress=False, check=False)
    assert (again.existing, len(again.skipped), again.exit_code, again.ok) == (1, 1, 1, False)


def test_a_run_that_skipped_every_file_does_not_block_the_fixed_rerun(tmp_path):
    """Every file skipped (here: a model folder without the gendered models); the rerun with the right
    model folder processes them instead of refusing "other settings"."""
    write_tree(tmp_path / "in", SEQUENCES)
    empty = tmp_path / "no_models"
    empty.mkdir()
    first = process_tree(tmp_path / "in", tmp_path / "out", ProcessOptions(model_path=str(empty)), workers=0,
                         progress=False, check=False)  # fmt: skip
    assert (first.done, len(first.skipped)) == (0, 2)
    assert "no male SMPL+H model" in dict(first.skipped)["a/s1_poses.npz"]
    fixed = process_tree(tmp_path / "in", tmp_path / "out", ProcessOptions(model_type="open"), workers=0,
                         progress=False)  # fmt: skip
    assert (fixed.done, fixed.existing, fixed.skipped) == (2, 0, [])
    assert not (tmp_path / "out" / LOCK_NAME).exists()
    # Once outputs exist, other settings are refused again.
    with pytest.raises(ProcessError, match="other settings"):
        process_tree(tmp_path / "in", tmp_path / "out", ProcessOptions(fps=10.0), workers=0, progress=False)


def test_size_warning_before_writing_says_how_much(tmp_path):
    write_sequence(tmp_path / "in" / "long_poses.npz", 300, 60.0, "smplh", "male")
    options = ProcessOptions(vertices=True, fps=30.0)
    tasks = find_inputs(tmp_path / "in", tmp_path / "out", options)
    estimate = estimate_output_bytes(tasks, options)
    vertices = 6890 if not OPEN_MODEL_PATH.exists() else int(np.load(OPEN_MODEL_PATH)["v_template"].shape[0])
    assert estimate == 150 * ((24 + vertices) * 3 * 4 + 8)  # 150 frames at 30 fps
    with pytest.warns(
        OutputSizeWarning, match=r"about 24\.1 MB will be written to .*out \(1 files\); the disk has [\d.]+ [MG]B free"
    ):
        process_tree(tmp_path / "in", tmp_path / "out", options, workers=0, progress=False, warn_bytes=1e6)
    written = (tmp_path / "out" / "long_poses.npz").stat().st_size
    assert estimate <= written <= estimate * 1.5  # the estimate is the arrays' size (faces and names besides)


def test_no_size_warning_under_the_threshold(tmp_path, recwarn):
    write_sequence(tmp_path / "in" / "short_poses.npz", 30, 60.0, "smplh", "male")
    process_tree(tmp_path / "in", tmp_path / "out", workers=0, progress=False, warn_bytes=1e6)
    assert not [w for w in recwarn if issubclass(w.category, OutputSizeWarning)]


@pytest.mark.parametrize("workers", ["2", "0"])
def test_ctrl_c_ends_a_vertex_run_promptly(tmp_path, workers):
    """SIGINT to ``smplcore process --vertices`` while workers are in the middle of long files: it ends
    (exit 130) within a few seconds, without finishing those files, and the rerun completes."""
    write_tree(tmp_path / "in", [(f"s{i}_poses.npz", 3000, 60.0, "male") for i in range(4)], seed=2)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "smplcore.cli", "process", str(tmp_path / "in"), str(out), "--vertices",
           "--workers", workers]  # fmt: skip
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.monotonic() + 60
    while not (out / "manifest.json").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(1.0)  # into the first files (each takes several seconds)
    proc.send_signal(signal.SIGINT)
    try:
        stdout, stderr = proc.communicate(timeout=5)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        pytest.fail("smplcore process did not end within 5 s of Ctrl-C")
    assert proc.returncode == 130, stderr
    assert "interrupted; finished outputs are kept, rerun to resume" in stderr
    assert not list(out.rglob("*.npz")), "a file finished after Ctrl-C"
    assert json.loads((out / "manifest.json").read_text())["status"] == "interrupted"
    assert not (out / LOCK_NAME).exists() and not [p for p in out.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize("index", [0, 1])
def test_the_python_blocks_of_docs_motion_run_as_scripts(tmp_path, index):
    import re

    text = (Path(__file__).resolve().parents[1] / "docs" / "motion.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert len(blocks) == 3  # the third (DMPL) needs fake official model files: tests/test_docs.py runs it
    (tmp_path / "block.py").write_text(blocks[index])
    done = subprocess.run([sys.executable, "block.py"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    if index == 0:
        assert lines == ["smplh male 120.0 240", "(20, 45, 3) (20, 13380, 3)", "(20, 24, 3)"]  # as the comments say
    else:
        assert lines[0].split()[:2] == ["2", "0"] and lines[0].split()[-1] == "0"  # 2 done, 0 existing, exit 0
        assert (tmp_path / "joints/CMU/01/01_01_poses.npz").exists()


def test_the_cli_prints_the_size_warning_as_one_line(tmp_path, monkeypatch, capsys):
    from smplcore.cli import main
    from smplcore.motion.process import run

    write_sequence(tmp_path / "in" / "long_poses.npz", 300, 60.0, "smplh", "male")
    monkeypatch.setattr(run, "DEFAULT_WARN_BYTES", 1e4)  # the run writes about 89 kB
    assert main(["process", str(tmp_path / "in"), str(tmp_path / "out"), "--workers", "0", "--quiet"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("smplcore process: warning: about 0.1 MB will be written to ")
    assert "(1 files); the disk has" in err[0]
