"""A seeded pickle/npz fuzzer (tests/pickle_fuzz.py) bounded to ~3 seconds: every mutated or random
input either loads or raises ModelFileError. It runs in a child process under RLIMIT_AS (1 GiB)
with a per-input alarm, so a crash, a hang or a blow-up fails this test instead of killing pytest."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent


@pytest.mark.parametrize("seed", [12])
def test_fuzzed_model_files_load_or_raise_model_file_error(seed):
    env = dict(os.environ, PYTHONPATH=str(TESTS.parent / "src"), OPENBLAS_NUM_THREADS="1")
    command = [sys.executable, "-W", "ignore", str(TESTS / "pickle_fuzz.py"), "--seed", str(seed), "--seconds", "3"]
    result = subprocess.run(command, capture_output=True, text=True, env=env, timeout=180)
    assert result.returncode == 0, f"the fuzzing child died ({result.returncode}): {result.stderr[-2000:]}"
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert report["failures"] == [] and report["counts"]["other"] == 0, report
    assert report["inputs"] >= 300, report  # it really ran
    assert report["counts"]["ok"] > 0 and report["counts"]["ModelFileError"] > 0, report
