"""A seeded fuzzer for the model-file loader: mutations of small real-structured files (legacy
pickles with chumpy and scipy.sparse objects, Python 3 pickles at protocols 2/4/5, stored and
deflated .npz archives) and random pickle opcode streams.

Every input is written to a file and loaded with ``load_model(path, model_type="open")``; the only
acceptable outcomes are a loaded model or a :class:`~smplcore.errors.ModelFileError` (one whose
message does not report a ``MemoryError``, which would mean a budget was not applied). Run it on its
own (it limits its address space to ``--memory-mb`` first)::

    PYTHONPATH=src python tests/pickle_fuzz.py --seed 1 --seconds 60

It prints one JSON line: counts per outcome and the first failures with their input's index.
"""

from __future__ import annotations

import argparse
import json
import pickle
import random
import re
import resource
import signal
import struct
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

_GLOBALS = [
    ("numpy", "dtype"),
    ("numpy", "ndarray"),
    ("numpy.core.multiarray", "_reconstruct"),
    ("numpy._core.multiarray", "scalar"),
    ("numpy.core.numeric", "_frombuffer"),
    ("copy_reg", "_reconstructor"),
    ("__builtin__", "object"),
    ("__builtin__", "set"),
    ("builtins", "list"),
    ("builtins", "bytes"),
    ("builtins", "bytearray"),
    ("builtins", "int"),
    ("builtins", "str"),
    ("_codecs", "encode"),
    ("chumpy.ch", "Ch"),
    ("scipy.sparse.csc", "csc_matrix"),
    ("scipy.sparse._coo", "coo_matrix"),
    ("os", "system"),
    ("builtins", "eval"),
    ("numpy", "load"),
]
_DTYPES = ["f8", "f4", "i8", "u4", "b1", "O8", "V8", "S3", "U2", "c16", "M8", "f8,i4"]
_INTS = [0, 1, -1, 2, 3, 7, 63, 255, 256, 2**31 - 1, -(2**31), 10**6]


def _random_opcodes(rng: random.Random) -> bytes:
    import hostile_files as H

    parts = [b"\x80" + bytes([rng.choice([2, 2, 4, 5])])]
    for _ in range(rng.randint(3, 60)):
        kind = rng.random()
        if kind < 0.15:
            parts.append(H.glob(*rng.choice(_GLOBALS)))
        elif kind < 0.25:
            shape = tuple(rng.choice([0, 1, 2, 3, 10**6]) for _ in range(rng.randint(0, 3)))
            data = bytes(rng.choice([0, 8, 16, 24, 48]))
            state = (3, rng.choice("<>|="), None, None, None, rng.choice([-1, 0, 8]), -1, rng.choice([0, 0, 63, 8]))
            parts.append(H.ndarray_op(H.dtype_op(rng.choice(_DTYPES), state), shape, data, fortran=rng.random() < 0.2))
        elif kind < 0.35:
            parts.append(H.integer(rng.choice(_INTS)))
        elif kind < 0.42:
            parts.append(H.text(rng.choice(["v_template", "f", "x", "latin1", "punycode", "a" * rng.randint(0, 300)])))
        elif kind < 0.47:
            parts.append(b"C" + bytes([n := rng.randint(0, 40)]) + rng.randbytes(n))
        elif kind < 0.55:
            parts.append(rng.choice([b"h", b"q"]) + bytes([rng.randint(0, 8)]))
        elif kind < 0.60:
            parts.append(rng.choice([b"j", b"r"]) + struct.pack("<I", rng.choice([0, 1, 2**31, 2**32 - 1])))
        elif kind < 0.65:
            parts.append(rng.choice([b"\x8e", b"\x8d", b"\x95", b"T", b"B", b"X"]) + rng.randbytes(rng.choice([4, 8])))
        else:
            parts.append(bytes([rng.choice(b"()]}t\x85\x86\x87lde\x8f\x90\x91Rbs\x81\x92u0120N\x88\x89.\x94")]))
    return b"".join(parts) + b"."


def _seeds() -> list[tuple[str, bytes]]:
    import numpy as np
    import scipy.sparse as sp

    import hostile_files as H
    from smplcore.io import ModelData, save_npz

    rng = np.random.default_rng(0)
    plain = {
        "v_template": rng.normal(size=(6, 3)),
        "f": np.array([[0, 1, 2], [2, 3, 4], [3, 4, 5]], dtype=np.uint32),
        "kintree_table": np.array([[4294967295, 0, 1], [0, 1, 2]], dtype=np.int64),
        "shapedirs": rng.normal(size=(6, 3, 2)),
        "J_regressor": sp.csc_matrix(np.full((3, 6), 1 / 6)),
        "weights": np.full((6, 3), 1 / 3),
        "posedirs": np.zeros((6, 3, 18)),
    }
    seeds = [("pkl", H.small_legacy_pickle())]
    seeds += [("pkl", pickle.dumps(plain, protocol=p)) for p in (2, 4, 5)]
    arrays = dict(plain, J_regressor=plain["J_regressor"].toarray())
    members = [{"name": f"{k}.npy", "data": H.npy_of(v)} for k, v in arrays.items()]
    with tempfile.TemporaryDirectory() as tmp:
        for method in (0, 8):
            path = H.write_zip(Path(tmp) / "x.npz", [dict(m, method=method) for m in members])
            seeds.append(("npz", path.read_bytes()))
        own = ModelData(
            model_type="open",
            gender="neutral",
            v_template=arrays["v_template"],
            faces=arrays["f"].astype(np.int64),
            shapedirs=arrays["shapedirs"],
            posedirs=None,
            J_regressor=arrays["J_regressor"],
            weights=arrays["weights"],
            parents=np.array([-1, 0, 1]),
            joint_names=("root", "a", "b"),
        )
        seeds.append(("npz", save_npz(own, Path(tmp) / "own.npz").read_bytes()))
    embedded = np.empty((), dtype=object)
    embedded[()] = dict(plain, J_regressor=arrays["J_regressor"])
    seeds.append(("npy", H.npy_of(embedded)))  # a .npy holding a pickled dict (as FLAME's embeddings)
    return seeds


def _mutate(rng: random.Random, data: bytes, seeds: list[tuple[str, bytes]]) -> bytes:
    out = bytearray(data)
    for _ in range(rng.choice([1, 1, 1, 2, 3, 8])):
        if not out:
            break
        op, i = rng.random(), rng.randrange(len(out))
        if op < 0.35:
            out[i] ^= 1 << rng.randrange(8)
        elif op < 0.5:
            out[i] = rng.choice([0, 0xFF, 0x7F, 0x80, ord("."), ord("b"), ord("R"), ord("("), ord("t")])
        elif op < 0.6:
            out[i : i + 4] = struct.pack("<I", rng.choice([0, 2**31 - 1, 2**32 - 1, 10**9]))
        elif op < 0.7:
            del out[i : i + rng.randint(1, 64)]
        elif op < 0.8:
            j = rng.randrange(len(out))
            out[i:i] = out[j : j + rng.randint(1, 64)]
        elif op < 0.9:
            del out[i:]
        else:
            other = rng.choice(seeds)[1]
            j = rng.randrange(len(other))
            out[i:] = other[j:]
    return bytes(out)


class _Hang(BaseException):
    """Raised by the per-input alarm; not an Exception, so no loader handler can swallow it."""


def run(seed: int, seconds: float, per_input: float = 2.0) -> dict:
    from smplcore.errors import ModelFileError
    from smplcore.io import load_model

    def alarm(signum, frame):
        raise _Hang()

    signal.signal(signal.SIGALRM, alarm)
    rng = random.Random(seed)
    seeds = _seeds()
    counts = {"ok": 0, "ModelFileError": 0, "other": 0}
    failures: list[dict] = []
    causes: dict[str, int] = {}
    start, index = time.monotonic(), 0
    with tempfile.TemporaryDirectory() as tmp:
        while time.monotonic() - start < seconds:
            if rng.random() < 0.3:
                kind, data = "pkl", _random_opcodes(rng)
            else:
                kind, base = rng.choice(seeds)
                data = base if rng.random() < 0.03 else _mutate(rng, base, seeds)
            path = Path(tmp) / f"model_{index}.{kind}"
            path.write_bytes(data)
            signal.setitimer(signal.ITIMER_REAL, per_input)
            try:
                load_model(path, model_type="open")
                outcome, message = "ok", ""
            except ModelFileError as exc:
                outcome, message = "ModelFileError", str(exc)
                if "MemoryError" in message:
                    outcome = "other"
            except _Hang:
                outcome, message = "other", f"no result after {per_input} s"
            except BaseException as exc:  # noqa: BLE001 - the point is to catch anything else
                outcome, message = "other", f"{type(exc).__name__}: {exc}"
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
            counts[outcome] += 1
            if outcome == "ModelFileError":
                cause = re.search(r"\((\w+(Error|Exception|File|error))\b", message)
                label = cause.group(1) if cause else ("refused" if "refused" in message else "checked value")
                causes[label] = causes.get(label, 0) + 1
            if outcome == "other" and len(failures) < 10:
                failures.append({"index": index, "kind": kind, "message": message[:300], "head": data[:80].hex()})
            path.unlink()
            index += 1
    top = dict(sorted(causes.items(), key=lambda kv: -kv[1]))
    return {"seed": seed, "inputs": index, "counts": counts, "failures": failures, "causes": top}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--memory-mb", type=int, default=1024)
    args = parser.parse_args()
    limit = args.memory_mb << 20
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    print(json.dumps(run(args.seed, args.seconds)))


if __name__ == "__main__":
    main()
