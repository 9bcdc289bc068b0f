"""Auxiliary files (priors, regressors, VPoser, deformation transfer, DMPL, UVs, keypoints, render inputs) are read
like model files: bounded, allow-listed, regular files only. Loads that could hang run in a child process
with a timeout, so a hang fails the test instead of stalling the suite."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from smplcore.errors import ModelFileError

TESTS = Path(__file__).resolve().parent
sys.path.insert(0, str(TESTS))

from aux_fuzz import nested_pickle  # noqa: E402

_ENV = dict(os.environ, PYTHONPATH=str(TESTS.parent / "src"), OPENBLAS_NUM_THREADS="1")

_CHILD = r"""
import json, resource, signal, sys, time
sys.path.insert(0, sys.argv[1])
resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))
from aux_fuzz import _readers
readers = _readers()
out = []
for name, path in json.loads(sys.stdin.read()):
    start = time.monotonic()
    try:
        readers[name][1](path)
        out.append([name, "ok", "", 0.0])
    except BaseException as exc:
        out.append([name, type(exc).__name__, str(exc)[:400], time.monotonic() - start])
print(json.dumps(out))
"""


def _load_in_child(cases: list[tuple[str, Path]], timeout: float = 240) -> list[tuple[str, str, str, float]]:
    """(reader, exception type, message, seconds) per case, from a child process limited to 2 GiB; a hang
    anywhere fails here (subprocess timeout)."""
    result = subprocess.run(
        [sys.executable, "-W", "ignore", "-c", _CHILD, str(TESTS)],
        input=json.dumps([[name, str(path)] for name, path in cases]),
        capture_output=True,
        text=True,
        env=_ENV,
        timeout=timeout,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    return [tuple(row) for row in json.loads(result.stdout.strip().splitlines()[-1])]


_PICKLE_READERS = ("gmm_prior", "keypoint_regressor", "deformation_transfer", "dmpl")


def test_a_384_byte_nested_pickle_fails_fast_naming_the_file(tmp_path):
    data = nested_pickle()  # {"means": L, "covars": L, "weights": L}, L = [[...], [...]] shared 37 deep
    assert len(data) <= 384
    cases = []
    for name in _PICKLE_READERS:
        path = tmp_path / f"{name}.pkl"
        keys = {"deformation_transfer": ("mtx",), "dmpl": ("eigvec",), "keypoint_regressor": ("J_regressor",)}
        path.write_bytes(data if name == "gmm_prior" else nested_pickle(keys[name]))
        cases.append((name, path))
    # VPoser as an .npz whose first weight is an object array holding the same kind of pickle
    import hostile_files as H

    member = H.npy_bytes(
        "{'descr': '|O', 'fortran_order': False, 'shape': (), }", H.PROTO2 + H.shared_list_ops(37) + b"."
    )
    vposer = H.write_zip(tmp_path / "vposer.npz", [{"name": "encoder_net.2.weight.npy", "data": member}])
    cases.append(("vposer", vposer))
    for name, kind, message, _seconds in _load_in_child(cases):
        assert kind == "ModelFileError", (name, kind, message)
        assert str(tmp_path) in message and "nested lists" in message, (name, message)


def test_non_regular_files_are_refused_without_opening_them(tmp_path):
    from aux_fuzz import _readers

    fifo = tmp_path / "input.fifo"
    os.mkfifo(fifo)
    loop = tmp_path / "loop.pkl"
    os.symlink(tmp_path / "loop2.pkl", loop)
    os.symlink(loop, tmp_path / "loop2.pkl")
    names = [n for n in _readers() if n not in ("openpose_json",)]  # (OpenPose also takes folders)
    cases = [(name, fifo) for name in _readers()] + [(name, loop) for name in names]
    for name, kind, message, _ in _load_in_child(cases):
        assert kind in ("ModelFileError", "FileNotFoundError", "ValueError"), (name, kind, message)
        assert "fifo" in message or "loop" in message, (name, message)
    fifo_rows = _load_in_child([("gmm_prior", fifo), ("keypoint_regressor", fifo), ("uv_obj", fifo)])
    assert all("not a regular file (a FIFO)" in row[2] for row in fifo_rows), fifo_rows


def test_aux_reader_refuses_over_shared_lists_but_reads_real_files(tmp_path):
    from smplcore.io.aux_files import read_arrays, read_json

    path = tmp_path / "ok.pkl"
    import pickle

    path.write_bytes(pickle.dumps({"names": ["a", "b"], "matrix": np.eye(3)}, 2))
    value = read_arrays(path, "a test file")
    assert value["names"] == ["a", "b"] and np.array_equal(value["matrix"], np.eye(3))
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(ModelFileError, match="deep.json.*nested too deep"):
        read_json(deep, "a test file")
    with pytest.raises(ModelFileError, match="is a directory, expected a test file"):
        read_arrays(tmp_path, "a test file")


def test_every_aux_reader_survives_crafted_and_fuzzed_files():
    """tests/aux_fuzz.py on every reader: crafted inputs, the reader's valid file and ~3 s of seeded mutations.
    0 hangs, 0 raw exceptions, 0 errors that do not name the file, nothing executed; memory within the bound."""
    command = [sys.executable, "-W", "ignore", str(TESTS / "aux_fuzz.py"), "--seed", "3", "--seconds", "3"]
    result = subprocess.run(command, capture_output=True, text=True, env=_ENV, timeout=900)
    assert result.returncode == 0, f"the fuzzing child died ({result.returncode}): {result.stderr[-2000:]}"
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert not report["executed"]
    total = report["total"]
    assert total["raw"] == 0 and total["hang"] == 0 and total["unclear"] == 0, {
        n: e["failures"] for n, e in report["readers"].items() if e["failures"]
    }
    for name, entry in report["readers"].items():
        assert entry["inputs"] >= 40, (name, entry["inputs"])
        assert entry["counts"]["clean"] >= 1, (name, entry)  # the valid file reads
        # the bound: the file's load budget (64 MiB + 8 x its size) for what is read, and as much again for
        # the one converted copy a reader may make (float64, dense)
        size = entry.get("peak_input_size", 0)
        assert entry["peak_bytes"] <= 2 * ((64 << 20) + 8 * size), (name, entry["peak_bytes"], entry["peak_input"])
