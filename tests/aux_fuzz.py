"""Crafted and fuzzed auxiliary files for every reader besides the model loader.

Readers: the GMM prior, keypoint regressors, VPoser, deformation transfer, DMPL, UV maps, OpenPose and COCO
keypoint files, the render / view inputs (motions, parameter sets, keypoints), export inputs, demo pose files,
AMASS motions and kid templates. Each gets the same crafted inputs (truncated, wrong dtype, huge declared
shapes, pickles whose lists are shared through the memo, deep tuples and JSON, object arrays, zip bombs and
forged member sizes, a pickle that would create a directory if anything in it ran, FIFOs, directories,
symlink loops, a link to ``/dev/zero``), its own valid file, and seeded mutations of it.

Outcomes per input: ``clean`` (read, no warning), ``flagged`` (read with a warning), ``clear`` (one of
smplcore's errors, or ValueError / FileNotFoundError, whose message names the file), ``unclear`` (such an
error that does not name the file), ``raw`` (any other exception), ``hang`` (no answer within the per-input
alarm). Peak memory per input is traced (``tracemalloc``, which NumPy reports to). Run it on its own (it
limits its address space first)::

    PYTHONPATH=src python tests/aux_fuzz.py --seed 1 --seconds 20

It prints one JSON line: per reader the counts, the largest peak and its input, the first failures.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import pickle
import random
import resource
import signal
import sys
import tempfile
import time
import tracemalloc
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import hostile_files as H  # noqa: E402

V = 12  # vertices of the small meshes the valid files are made for


class _Hang(BaseException):
    """Raised by the per-input alarm; not an Exception, so no reader's handler can swallow it."""


# -- the readers -------------------------------------------------------------------------------------


def _readers() -> dict[str, tuple[tuple[str, ...], Callable[[Path], object]]]:
    from smplcore.demo import load_pose_file
    from smplcore.export.inputs import load_input
    from smplcore.fit.convert import read_deformation_transfer
    from smplcore.fit.priors import GMMPrior
    from smplcore.fit.vposer import VPoserPrior
    from smplcore.io.containers import read_array_file
    from smplcore.io.dmpl import load_dmpl
    from smplcore.io.uv import load_uv_obj
    from smplcore.keypoints import read_coco, read_openpose
    from smplcore.keypoints.regressor import Regressor
    from smplcore.motion import load_motion
    from smplcore.view.sources import load_keypoints, load_source

    return {
        "gmm_prior": ((".pkl",), GMMPrior.load),
        "keypoint_regressor": ((".pkl", ".npy", ".npz"), Regressor.load),
        "vposer": ((".ckpt", ".npz"), VPoserPrior.load),
        "deformation_transfer": ((".pkl",), lambda p: read_deformation_transfer(p, V, V)),
        "dmpl": ((".npz",), load_dmpl),
        "uv_obj": ((".obj",), load_uv_obj),
        "openpose_json": ((".json",), read_openpose),
        "coco_json": ((".json",), read_coco),
        "render_keypoints": ((".npy", ".npz"), load_keypoints),
        "render_source": ((".npz", ".json"), load_source),
        "export_input": ((".npz", ".json"), load_input),
        "demo_pose": ((".npy", ".npz", ".txt"), load_pose_file),
        "motion": ((".npz",), load_motion),
        "kid_template": ((".npy",), read_array_file),
    }


# -- valid files ----------------------------------------------------------------------------------


def _npz(**arrays: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _npy(array: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, array, allow_pickle=False)
    return buf.getvalue()


def _valid(name: str, suffix: str) -> bytes:
    rng = np.random.default_rng(0)
    if name == "gmm_prior":
        a = rng.normal(0, 0.1, (2, 6, 6))
        cov = a @ np.swapaxes(a, 1, 2) + 0.1 * np.eye(6)
        return pickle.dumps({"means": rng.normal(0, 0.1, (2, 6)), "covars": cov, "weights": np.array([0.4, 0.6])}, 2)
    if name == "keypoint_regressor":
        matrix = np.abs(rng.normal(size=(3, V)))
        matrix /= matrix.sum(1, keepdims=True)
        if suffix == ".npy":
            return _npy(matrix)
        if suffix == ".npz":
            return _npz(J_regressor=matrix)
        import scipy.sparse as sp

        return pickle.dumps({"J_regressor": sp.csc_matrix(matrix)}, 2)
    if name == "vposer":
        from smplcore.fit.vposer import _layers

        arrays = {k: rng.normal(0, 0.1, s).astype(np.float32) for k, s in _layers(8, 4).items()}
        for k in arrays:
            if k.endswith("running_var"):
                arrays[k] = np.abs(arrays[k]) + 1
        return _npz(**arrays)
    if name == "deformation_transfer":
        import scipy.sparse as sp

        return pickle.dumps({"mtx": sp.csr_matrix((np.ones(V), (np.arange(V), np.arange(V))), shape=(V, 2 * V))}, 2)
    if name == "dmpl":
        return _npz(eigvec=rng.normal(size=(V, 3, 8)))
    if name == "uv_obj":
        return b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n"
    if name == "openpose_json":
        return json.dumps({"version": 1.3, "people": [{"pose_keypoints_2d": [1.0, 2.0, 0.9] * 25}]}).encode()
    if name == "coco_json":
        return json.dumps(
            {
                "images": [{"id": 1, "width": 640, "height": 480}],
                "annotations": [{"id": 1, "image_id": 1, "category_id": 1, "keypoints": [10, 20, 2] * 17}],
                "categories": [{"id": 1, "name": "person", "keypoints": [f"k{i}" for i in range(17)]}],
            }
        ).encode()
    if name == "render_keypoints":
        points = rng.normal(size=(4, 5, 3))
        return _npy(points) if suffix == ".npy" else _npz(keypoints=points)
    if name in ("render_source", "export_input"):
        params = {"betas": rng.normal(size=(1, 10)), "body_pose": rng.normal(0, 0.1, (1, 69))}
        if suffix == ".json":
            return json.dumps({k: v.tolist() for k, v in params.items()}).encode()
        return _npz(**params)
    if name == "demo_pose":
        pose = rng.normal(0, 0.1, (2, 69))
        if suffix == ".txt":
            return "\n".join(" ".join(f"{x:.4f}" for x in row) for row in pose).encode()
        return _npy(pose) if suffix == ".npy" else _npz(body_pose=pose)
    if name == "motion":
        return _npz(
            poses=rng.normal(0, 0.1, (3, 156)),
            trans=np.zeros((3, 3)),
            betas=np.zeros(16),
            mocap_framerate=np.array(30.0),
            gender=np.array("neutral"),
        )
    if name == "kid_template":
        return _npy(rng.normal(size=(V, 3)))
    raise KeyError(name)


# -- crafted files ---------------------------------------------------------------------------------

_KEYS = ("means", "covars", "weights", "mtx", "eigvec", "J_regressor", "poses", "keypoints", "body_pose", "betas")


def nested_pickle(keys: tuple[str, ...] = ("means", "covars", "weights"), levels: int = 37) -> bytes:
    """A pickled dict whose values are one list ``L[i+1] = [L[i], L[i]]`` shared through the memo: a few
    hundred bytes (384 for the GMM keys), 2**levels leaves for anything that walks it."""
    out = H.PROTO2 + b"}" + H.text(keys[0]) + H.shared_list_ops(levels) + b"s"
    for key in keys[1:]:
        out += H.text(key) + b"h" + bytes([levels]) + b"s"
    return out + b"."


def _crafted_binary(marker: Path) -> dict[str, bytes]:
    good = np.zeros((4, 3))
    npy = _npy(good)
    runs = H.reduce(H.glob("posix", "mkdir"), H.text(str(marker)))  # os.mkdir(marker) if anything ran
    bomb_member = H.zeros_deflated(
        64 << 20, H.npy_bytes("{'descr': '<f8', 'fortran_order': False, 'shape': (8388608,), }")
    )
    return {
        "empty": b"",
        "garbage": bytes(random.Random(1).randrange(256) for _ in range(64)),
        "nested_pickle": nested_pickle(_KEYS),
        "nested_pickle_384": nested_pickle(),
        "deep_tuple": H.deep_tuple_key(200_000),
        "list_copy_bomb": H.list_copy_bomb(2000, 3000),
        "runs_code_pickle": H.PROTO2 + b"}" + H.text("means") + runs + b"s.",
        "runs_code_npy": H.npy_bytes("{'descr': '|O', 'fortran_order': False, 'shape': (), }", H.PROTO2 + runs + b"."),
        "object_npy": H.npy_of(np.array({"means": [1, 2]}, dtype=object)),
        "object_array_npy": H.npy_of(np.array([None, "x", 3], dtype=object)),
        "complex_npy": _npy(np.ones((4, 3), complex)),
        "string_npy": _npy(np.array(["a", "b"])),
        "structured_npy": _npy(np.zeros(3, dtype=[("a", "<f8"), ("b", "<i4")])),
        "huge_shape_npy": H.npy_bytes("{'descr': '<f8', 'fortran_order': False, 'shape': (1000000, 1000000), }"),
        "huge_truncated_npy": H.npy_bytes(
            "{'descr': '<f8', 'fortran_order': False, 'shape': (10000000,), }", b"\0" * 64
        ),
        "truncated_npy": npy[: len(npy) - 20],
        "truncated_pickle": pickle.dumps({"means": good}, 2)[:-30],
        "nested_npz": _npz_bytes(
            [
                {
                    "name": f"{k}.npy",
                    "data": H.npy_bytes(
                        "{'descr': '|O', 'fortran_order': False, 'shape': (), }",
                        H.PROTO2 + H.shared_list_ops(40) + b".",
                    ),
                }
                for k in _KEYS
            ]
        ),  # fmt: skip
        "zip_bomb_npz": _npz_bytes(
            [
                {"name": f"{k}.npy", "data": bomb_member, "method": 8, "raw": True, "size": (64 << 20) + 128}
                for k in _KEYS
            ]
        ),
        "forged_size_npz": _npz_bytes(
            [{"name": f"{k}.npy", "data": b"x" * 100, "method": 8, "raw": True, "size": 10**9} for k in _KEYS]
        ),
        "truncated_npz": _npz(**{k: good for k in _KEYS})[:-40],
        "nan_npz": _npz(**{k: np.full((4, 3), np.nan) for k in _KEYS}),
        "wrong_shape_npz": _npz(**{k: np.zeros((2, 2, 2, 2)) for k in _KEYS}),
    }


def _npz_bytes(members: list[dict]) -> bytes:
    with tempfile.TemporaryDirectory() as tmp:
        return H.write_zip(Path(tmp) / "m.npz", members).read_bytes()


def _crafted_text() -> dict[str, bytes]:
    return {
        "empty": b"",
        "deep_json": b"[" * 200_000,
        "deep_json_closed": b"[" * 50_000 + b"]" * 50_000,
        "long_int_json": b"1" * 100_000,
        "invalid_utf8": b"\xff\xfe{\x00",
        "wrong_types_json": b'{"people": 5, "annotations": {"a": 1}, "images": 3, "poses": "x", "betas": [[1], 2]}',
        "nan_json": b'{"people": [{"pose_keypoints_2d": [NaN, Infinity, 1]}], "betas": [NaN], "poses": [[NaN]]}',
        "unhashable_ids_json": b'{"images": [{"id": [1], "width": 1, "height": 1}], "annotations": '
        b'[{"image_id": [1], "category_id": 1, "keypoints": [1, 2, 2]}], "categories": [{"id": 1}]}',
        "malformed_obj": b"v 0 0 0\nvt 1 x\nf 1/1 2/2\n",
        "obj_out_of_range": b"vt 0 0\nf 1/1 2/9 3/-7\n",
        "text_table_garbage": b"1 2 3\n4 five 6\n",
    }


def _special(tmp: Path, suffix: str, index: int) -> dict[str, Path]:
    """Paths that are no regular file: a FIFO, a directory, a symlink loop, a dangling link, /dev/zero."""
    base = tmp / f"special_{index}"
    base.mkdir()
    fifo = base / f"fifo{suffix}"
    os.mkfifo(fifo)
    folder = base / f"folder{suffix}"
    folder.mkdir()
    loop_a, loop_b = base / f"loop_a{suffix}", base / f"loop_b{suffix}"
    os.symlink(loop_b, loop_a)
    os.symlink(loop_a, loop_b)
    dangling = base / f"dangling{suffix}"
    os.symlink(base / "nothing", dangling)
    zero = base / f"zero{suffix}"
    os.symlink("/dev/zero", zero)
    return {"fifo": fifo, "directory": folder, "symlink_loop": loop_a, "dangling_link": dangling, "dev_zero": zero}


def _mutate(rng: random.Random, data: bytes) -> bytes:
    out = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        if not out:
            break
        i = rng.randrange(len(out))
        op = rng.random()
        if op < 0.4:
            out[i] = rng.randrange(256)
        elif op < 0.6:
            del out[i:]
        elif op < 0.8:
            out[i:i] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 8)))
        else:
            j = rng.randrange(len(out))
            out[i:i] = out[j : j + rng.randint(1, 64)]
    return bytes(out)


# -- running ---------------------------------------------------------------------------------------


def _classify(path: Path, call: Callable[[Path], object], per_input: float) -> tuple[str, str, int]:
    """(outcome, message, peak traced bytes) of ``call(path)``."""
    from smplcore.errors import ModelFileError, ShapeError

    tracemalloc.reset_peak()
    before = tracemalloc.get_traced_memory()[0]
    signal.setitimer(signal.ITIMER_REAL, per_input)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            call(path)
        outcome, message = ("flagged" if caught else "clean"), (str(caught[0].message) if caught else "")
    except _Hang:
        outcome, message = "hang", f"no answer after {per_input} s"
    except (ModelFileError, ShapeError, ValueError, FileNotFoundError) as exc:
        message = str(exc)
        named = path.name in message or path.parent.name in message or str(path) in message
        outcome = "clear" if named and "MemoryError" not in message else "unclear"
    except BaseException as exc:  # noqa: BLE001 - the point is to catch anything else
        outcome, message = "raw", f"{type(exc).__name__}: {exc}"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
    peak = tracemalloc.get_traced_memory()[1] - before
    return outcome, message[:300], peak


def run(seed: int, seconds: float, per_input: float = 5.0, only: str | None = None) -> dict:
    def alarm(signum, frame):
        raise _Hang()

    signal.signal(signal.SIGALRM, alarm)
    readers = _readers()
    if only:
        readers = {k: v for k, v in readers.items() if k in only.split(",")}
    rng = random.Random(seed)
    report: dict[str, dict] = {}
    tracemalloc.start()
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        marker = tmp / "ran"
        binary, text = _crafted_binary(marker), _crafted_text()
        mutation_deadline = time.monotonic() + seconds
        for r_index, (name, (suffixes, call)) in enumerate(readers.items()):
            counts = dict.fromkeys(("clean", "flagged", "clear", "unclear", "raw", "hang"), 0)
            entry: dict = {"counts": counts, "failures": [], "peak_bytes": 0, "peak_input": "", "inputs": 0}
            report[name] = entry

            def record(label: str, path: Path, size: int) -> None:
                outcome, message, peak = _classify(path, call, per_input)  # noqa: B023 - used at once
                counts[outcome] += 1  # noqa: B023
                entry["inputs"] += 1  # noqa: B023
                if peak > entry["peak_bytes"]:  # noqa: B023
                    entry.update(peak_bytes=peak, peak_input=label, peak_input_size=size)  # noqa: B023
                if outcome in ("unclear", "raw", "hang") and len(entry["failures"]) < 8:  # noqa: B023
                    entry["failures"].append({"input": label, "outcome": outcome, "message": message})  # noqa: B023

            for s_index, suffix in enumerate(suffixes):
                folder = tmp / f"{name}{s_index}"
                folder.mkdir()
                is_text = suffix in (".json", ".obj", ".txt")
                valid = _valid(name, suffix)
                cases = {"valid": valid, **(text if is_text else binary)}
                if is_text:
                    cases["binary_garbage"] = binary["garbage"]
                else:
                    cases["text_json"] = text["deep_json"]
                for label, data in cases.items():
                    path = folder / f"{label}{suffix}"
                    path.write_bytes(data)
                    record(f"{label}{suffix}", path, len(data))
                for label, path in _special(tmp, suffix, 100 * r_index + s_index).items():
                    record(f"{label}{suffix}", path, 0)
                # seeded mutations of the valid file, sharing what is left of the time budget
                share = (mutation_deadline - time.monotonic()) / max(1, len(readers) * 2 - 2 * r_index - s_index)
                stop = time.monotonic() + max(0.2, share)
                k = 0
                while time.monotonic() < stop:
                    data = _mutate(rng, valid)
                    path = folder / f"mutant_{k}{suffix}"
                    path.write_bytes(data)
                    record(f"mutant_{k}{suffix}", path, len(data))
                    path.unlink()
                    k += 1
        executed = marker.exists()
    tracemalloc.stop()
    total = {k: sum(e["counts"][k] for e in report.values()) for k in next(iter(report.values()))["counts"]}
    return {"seed": seed, "readers": report, "total": total, "executed": executed}


def run_fit_cli(per_input: float = 60.0) -> dict:
    """``smplcore fit`` on the crafted files as INPUT (``.npy`` joints, ``.npz`` motion, ``.json`` COCO, specials)
    and as ``--gmm`` / ``--vposer``; outcomes: ``clean`` (status 0), ``clear`` (status 1 or 2, stderr names
    the file, no traceback), ``unclear``, ``raw`` (an exception out of ``main``), ``hang``."""
    import contextlib

    from smplcore.cli import main as cli_main

    def alarm(signum, frame):
        raise _Hang()

    signal.signal(signal.SIGALRM, alarm)
    counts = dict.fromkeys(("clean", "flagged", "clear", "unclear", "raw", "hang"), 0)
    failures: list[dict] = []
    names = "pelvis,left_hip,right_hip,spine1,left_knee,right_knee"
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        binary, text = _crafted_binary(tmp / "ran"), _crafted_text()
        valid = tmp / "valid.npy"
        valid.write_bytes(_npy(np.random.default_rng(0).normal(size=(3, 6, 3))))
        cases: list[tuple[str, list[str], Path]] = []
        for suffix, extra in ((".npy", ["--joint-names", names]), (".npz", []), (".json", ["--image-size", "64,48"])):
            for label, data in {**(text if suffix == ".json" else binary), "valid": None}.items():
                path = tmp / f"{label}{suffix}"
                if data is None:
                    if suffix != ".npy":
                        continue
                    path = valid
                else:
                    path.write_bytes(data)
                cases.append((f"input {label}{suffix}", [str(path), *extra], path))
            for label, path in _special(tmp, suffix, len(cases)).items():
                cases.append((f"input {label}{suffix}", [str(path), *extra], path))
        for option, suffix in (("--gmm", ".pkl"), ("--vposer", ".npz")):
            for label, data in binary.items():
                path = tmp / f"prior_{label}{suffix}"
                path.write_bytes(data)
                cases.append((f"{option} {label}", [str(valid), "--joint-names", names, option, str(path)], path))
            for label, path in _special(tmp, suffix, len(cases)).items():
                cases.append((f"{option} {label}", [str(valid), "--joint-names", names, option, str(path)], path))
        for k, (label, argv, path) in enumerate(cases):
            out = tmp / f"out_{k}.npz"
            err = io.StringIO()
            signal.setitimer(signal.ITIMER_REAL, per_input)
            try:
                with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                    status = cli_main(["fit", *argv, "-o", str(out), "--no-progress"])
                message = err.getvalue()
                if status == 0:
                    outcome = "clean"
                else:
                    named = path.name in message or str(path) in message or str(path.resolve()) in message
                    outcome = "clear" if named and status in (1, 2) and "Traceback" not in message else "unclear"
            except _Hang:
                outcome, message = "hang", f"no answer after {per_input} s"
            except SystemExit as exc:  # argparse
                outcome, message = ("clear" if exc.code == 2 else "unclear"), err.getvalue()
            except BaseException as exc:  # noqa: BLE001
                outcome, message = "raw", f"{type(exc).__name__}: {exc}"
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
            counts[outcome] += 1
            if outcome in ("unclear", "raw", "hang") and len(failures) < 10:
                failures.append({"input": label, "outcome": outcome, "message": message[-300:]})
        executed = (tmp / "ran").exists()
    return {"inputs": len(cases), "counts": counts, "failures": failures, "executed": executed}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--seconds", type=float, default=4.0, help="time for the seeded mutations, all readers")
    parser.add_argument("--memory-mb", type=int, default=2048)
    parser.add_argument("--only", default=None, help="comma-separated reader names")
    parser.add_argument("--fit-cli", action="store_true", help="the `smplcore fit` command instead of the readers")
    args = parser.parse_args()
    limit = args.memory_mb << 20
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    print(json.dumps(run_fit_cli() if args.fit_cli else run(args.seed, args.seconds, only=args.only)))


if __name__ == "__main__":
    main()
