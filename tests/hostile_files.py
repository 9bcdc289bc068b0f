"""Builders of hostile and broken model files for the loader tests: hand-assembled pickle opcode
streams, raw zip archives (any flags, methods and declared sizes), ``.npy`` headers, zip bombs.

Nothing here writes a payload that does harm if run: "unsafe" pickles name globals that would
only fail or print, and the tests assert they are refused before being called.
"""

from __future__ import annotations

import pickle
import struct
import zlib
from pathlib import Path

import numpy as np
import scipy.sparse as sp

# ---------------------------------------------------------------------------------------------
# Pickle opcodes
# ---------------------------------------------------------------------------------------------

PROTO2 = b"\x80\x02"


def glob(module: str, name: str) -> bytes:
    """GLOBAL opcode."""
    return b"c" + module.encode() + b"\n" + name.encode() + b"\n"


def text(s: str) -> bytes:
    """BINUNICODE."""
    data = s.encode("utf-8")
    return b"X" + struct.pack("<I", len(data)) + data


def py2str(data: bytes) -> bytes:
    """BINSTRING (a Python 2 ``str``), as official files hold byte strings."""
    return b"T" + struct.pack("<i", len(data)) + data


def integer(n: int) -> bytes:
    """BININT (signed 32-bit)."""
    return b"J" + struct.pack("<i", n)


def long_(n: int) -> bytes:
    """LONG1 (any Python int)."""
    data = n.to_bytes((n.bit_length() + 8) // 8, "little", signed=True)
    return b"\x8a" + bytes([len(data)]) + data


def tup(*items: bytes) -> bytes:
    """MARK items TUPLE."""
    return b"(" + b"".join(items) + b"t"


def reduce(func: bytes, *args: bytes) -> bytes:
    return func + tup(*args) + b"R"


def dtype_op(type_str: str, state: tuple | None = None) -> bytes:
    """``numpy.dtype(type_str, False, True)`` then BUILD with numpy's state tuple (or ``state``)."""
    if state is None:
        state = (3, "<", None, None, None, -1, -1, 0)
    return reduce(glob("numpy", "dtype"), text(type_str), b"\x89", b"\x88") + obj(state) + b"b"


def obj(value) -> bytes:
    """A plain value (tuple, int, str, bytes, None, bool) as opcodes."""
    if value is None:
        return b"N"
    if value is True:
        return b"\x88"
    if value is False:
        return b"\x89"
    if isinstance(value, int):
        return integer(value)
    if isinstance(value, str):
        return text(value)
    if isinstance(value, bytes):
        return b"B" + struct.pack("<I", len(value)) + value
    if isinstance(value, tuple):
        return tup(*(obj(v) for v in value))
    raise TypeError(value)


def ndarray_op(dtype: bytes, shape: tuple, data: bytes, fortran: bool = False, version: bool = True) -> bytes:
    """``_reconstruct(ndarray, (0,), b'b')`` then BUILD ``(1, shape, dtype, fortran, data)``."""
    recon = reduce(glob("numpy.core.multiarray", "_reconstruct"), glob("numpy", "ndarray"), obj((0,)), obj(b"b"))
    fields = ([integer(1)] if version else []) + [obj(shape), dtype, obj(fortran), py2str(data)]
    return recon + tup(*fields) + b"b"


def dict_of(**items: bytes) -> bytes:
    """A pickle (protocol 2) of a dict whose values are the given opcode streams."""
    body = b"".join(text(k) + v for k, v in items.items())
    return PROTO2 + b"}(" + body + b"u."


def one_value(value: bytes) -> bytes:
    return PROTO2 + value + b"."


def float_array(shape: tuple, fill: float = 0.0) -> bytes:
    """Opcodes of a float64 ndarray (legitimate)."""
    return ndarray_op(dtype_op("f8"), shape, np.full(shape, fill).tobytes())


def deep_tuple_key(depth: int) -> bytes:
    """A dict whose key is a tuple nested ``depth`` deep (hashing it overflows the C stack)."""
    return PROTO2 + b"}" + b")" + b"\x85" * depth + b"K\x01s."


def shared_list_ops(levels: int) -> bytes:
    """Opcodes of ``L[i+1] = [L[i], L[i]]`` (memo slots 0..levels): 2**levels leaves if copied."""
    out = b"]q\x00"
    for i in range(levels):  # POP the previous list, build the next from two references to it
        out += b"0(h" + bytes([i]) + b"h" + bytes([i]) + b"lq" + bytes([i + 1])
    return out


def shared_list_bomb(levels: int) -> bytes:
    """A dict whose ``v_template`` is :func:`shared_list_ops`."""
    return PROTO2 + b"}" + text("v_template") + shared_list_ops(levels) + b"s."


def list_copy_bomb(size: int, copies: int) -> bytes:
    """One list of ``size`` items copied ``copies`` times through ``builtins.list`` (quadratic)."""
    out = PROTO2 + b"]q\x00(" + b"K\x01" * size + b"e" + glob("__builtin__", "list") + b"q\x01"
    out += b"]("
    for _ in range(copies):
        out += b"h\x01h\x00\x85R"
    return out + b"e."


# ---------------------------------------------------------------------------------------------
# .npy and zip
# ---------------------------------------------------------------------------------------------


def npy_bytes(header: str, data: bytes = b"", version: int = 1) -> bytes:
    """A .npy file with the header dict text given verbatim."""
    h = header.encode("latin1")
    h += b" " * ((64 - (len(h) + 11) % 64) % 64) + b"\n"
    if version == 1:
        return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(h)) + h + data
    return b"\x93NUMPY\x02\x00" + struct.pack("<I", len(h)) + h + data


def npy_of(array: np.ndarray) -> bytes:
    import io

    buf = io.BytesIO()
    np.lib.format.write_array(buf, array, allow_pickle=True)
    return buf.getvalue()


def zeros_deflated(nbytes: int, prefix: bytes = b"") -> bytes:
    """A raw deflate stream inflating to ``prefix`` then ``nbytes`` zero bytes, built fast by
    repeating one fully-flushed (self-contained) block."""
    chunk = 1 << 22
    head = zlib.compressobj(9, zlib.DEFLATED, -15)
    start = head.compress(prefix) + head.flush(zlib.Z_FULL_FLUSH) if prefix else b""
    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    block = c.compress(bytes(chunk)) + c.flush(zlib.Z_FULL_FLUSH)
    tail = zlib.compressobj(9, zlib.DEFLATED, -15)
    rest = tail.compress(bytes(nbytes % chunk)) + tail.flush()
    return start + block * (nbytes // chunk) + rest


def write_zip(path: Path, members: list[dict]) -> Path:
    """A zip archive written byte by byte. Each member: ``name``, ``data`` (stored as given),
    optional ``method`` (0 stored, 8 deflate, ...), ``flags``, ``size`` (declared uncompressed size,
    default ``len(data)`` for stored), ``crc``. Deflate members are compressed unless ``raw``."""
    out, central = bytearray(), bytearray()
    for m in members:
        name = m["name"].encode()
        method = m.get("method", 0)
        data = m["data"]
        if method == 8 and not m.get("raw"):
            c = zlib.compressobj(6, zlib.DEFLATED, -15)
            payload = c.compress(data) + c.flush()
        else:
            payload = data
        size = m.get("size", len(data))
        crc = m.get("crc", zlib.crc32(data) if not m.get("raw") else 0)
        flags = m.get("flags", 0)
        offset = len(out)
        fields = (20, flags, method, 0, 0, crc, len(payload), size, len(name), 0)
        out += b"PK\x03\x04" + struct.pack("<HHHHHIIIHH", *fields) + name + payload
        central += b"PK\x01\x02" + struct.pack(
            "<HHHHHHIIIHHHHHII", 20, 20, flags, method, 0, 0, crc, len(payload), size, len(name), 0, 0, 0, 0, 0, offset
        )
        central += name
    n = len(members)
    end = b"PK\x05\x06" + struct.pack("<HHHHIIH", 0, 0, n, n, len(central), len(out), 0)
    path.write_bytes(bytes(out + central + end))
    return path


# ---------------------------------------------------------------------------------------------
# Small, real-structured seeds for the fuzzer
# ---------------------------------------------------------------------------------------------


def small_legacy_pickle() -> bytes:
    """A small model-like pickle written the way official files are (protocol 2, Python 2 strings,
    legacy module names): arrays, a chumpy ``Ch``, a ``csc_matrix``, a set, nested dicts."""
    import io

    import fakes

    rng = np.random.default_rng(0)
    value = {
        "v_template": rng.normal(size=(6, 3)),
        "f": np.array([[0, 1, 2], [2, 3, 4], [3, 4, 5]], dtype=np.uint32),
        "kintree_table": np.array([[4294967295, 0, 1], [0, 1, 2]], dtype=np.int64),
        "shapedirs": fakes._ch(rng.normal(size=(6, 3, 2))),
        "J_regressor": sp.csc_matrix(np.abs(rng.normal(size=(3, 6))) * (rng.random((3, 6)) > 0.5)),
        "weights": np.full((6, 3), 1 / 3),
        "posedirs": np.zeros((6, 3, 18)),
        "bs_style": "lbs",
        "pose_training_info": {"set": {1, 2}, "name": "x", "n": 3.5},
    }
    buf = io.BytesIO()
    fakes._LegacyPickler(buf, protocol=2, py2_strings=True).dump(value)
    return buf.getvalue()


def small_npz_members() -> dict[str, bytes]:
    """Members of a small official-like .npz (with a 0-d object array, as real ones have)."""
    rng = np.random.default_rng(1)
    pose_info = np.empty((), dtype=object)
    pose_info[()] = {"a": np.arange(3)}
    arrays = {
        "v_template": rng.normal(size=(6, 3)),
        "f": np.array([[0, 1, 2], [2, 3, 4]], dtype=np.uint32),
        "kintree_table": np.array([[-1, 0, 1], [0, 1, 2]]),
        "weights": np.full((6, 3), 1 / 3),
        "bs_type": np.array("lrotmin"),
        "joint2num": pose_info,
    }
    return {f"{k}.npy": npy_of(v) for k, v in arrays.items()}


def dumps(value, protocol: int = 2) -> bytes:
    return pickle.dumps(value, protocol=protocol)


# ---------------------------------------------------------------------------------------------
# Running loads in a child process with limits
# ---------------------------------------------------------------------------------------------

SRC = Path(__file__).resolve().parents[1] / "src"

_CHILD = r"""
import json, resource, sys
limit = int(sys.argv[1]) << 20
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
import smplcore
from smplcore.errors import ModelFileError
from smplcore.io import load_model
out = []
for path in json.loads(sys.stdin.read()):
    try:
        data = load_model(path)
        out.append(["ok", data.model_type])
    except ModelFileError as exc:
        out.append(["ModelFileError", str(exc)])
    except BaseException as exc:
        out.append(["other", f"{type(exc).__name__}: {exc}"[:500]])
print(json.dumps(out))
"""


def load_in_child(paths: list, memory_mb: int = 1024, timeout: float = 120) -> list[tuple[str, str]]:
    """``load_model`` on each path in a child process limited to ``memory_mb`` of address space;
    returns ``(outcome, message)`` per path, outcome ``ok`` / ``ModelFileError`` / ``other``.
    A crash or a timeout of the child raises AssertionError."""
    import json
    import os
    import subprocess
    import sys

    env = dict(os.environ, PYTHONPATH=str(SRC), OPENBLAS_NUM_THREADS="1")
    result = subprocess.run(
        [sys.executable, "-c", _CHILD, str(memory_mb)],
        input=json.dumps([str(p) for p in paths]),
        capture_output=True,
        text=True,
        env=env,
        timeout=timeout,
    )
    assert result.returncode == 0, f"child died with {result.returncode}: {result.stderr[-2000:]}"
    return [tuple(item) for item in json.loads(result.stdout.strip().splitlines()[-1])]
