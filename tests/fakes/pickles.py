"""Containers as the official files use them: Python 2 pickles with legacy global names, chumpy
``Ch``, 0-d object ``.npy`` files and ``.npz`` archives that may hold any key."""

from __future__ import annotations

import pickle
import struct
import zipfile
from pathlib import Path

import numpy as np
import scipy.sparse as sp


def _legacy_global(module: str, name: str) -> tuple[str, str]:
    """Map today's module paths to those in files written with old numpy / scipy / Python 2."""
    if module == "numpy._core" or module.startswith("numpy._core."):
        module = "numpy.core" + module[len("numpy._core") :]
    elif module.startswith("scipy.sparse._") and name.endswith("_matrix"):
        module = "scipy.sparse." + module[len("scipy.sparse._") :]
    if module == "builtins":
        module = "__builtin__"
    return module, name


class _LegacyPickler(pickle._Pickler):  # the pure-Python pickler, so opcodes can be chosen
    """Pickler writing what Python 2 (protocol 2) / old numpy and scipy wrote.

    With ``py2_strings`` every ``bytes`` and every ASCII ``str`` becomes a Python 2 ``str``
    (``SHORT_BINSTRING`` / ``BINSTRING``); non-ASCII text stays ``unicode`` (``BINUNICODE``).
    Global names are mapped with :func:`_legacy_global`.
    """

    dispatch = pickle._Pickler.dispatch.copy()

    def __init__(self, file, protocol: int = 2, py2_strings: bool = True):
        super().__init__(file, protocol=protocol, fix_imports=True)
        self.py2_strings = py2_strings and protocol <= 2

    def _write_py2_str(self, data: bytes, obj) -> None:
        n = len(data)
        if n < 256:
            self.write(pickle.SHORT_BINSTRING + bytes([n]))
        else:
            self.write(pickle.BINSTRING + struct.pack("<i", n))
        self.write(data)
        self.memoize(obj)

    def save_bytes(self, obj):
        if self.py2_strings:
            self._write_py2_str(obj, obj)
        else:
            pickle._Pickler.save_bytes(self, obj)

    def save_str(self, obj):
        if self.py2_strings and obj.isascii():
            self._write_py2_str(obj.encode("ascii"), obj)
        else:
            pickle._Pickler.save_str(self, obj)

    dispatch[bytes] = save_bytes
    dispatch[str] = save_str

    def save_global(self, obj, name=None):
        if name is None:
            name = getattr(obj, "__qualname__", None) or obj.__name__
        module = pickle.whichmodule(obj, name)
        module, name = _legacy_global(module, name)
        if self.proto >= 4:
            self.save(module)
            self.save(name)
            self.write(pickle.STACK_GLOBAL)
        else:
            self.write(pickle.GLOBAL + module.encode("ascii") + b"\n" + name.encode("ascii") + b"\n")
        self.memoize(obj)


def dump_legacy_pickle(obj, path, protocol: int = 2, py2_strings: bool = True) -> Path:
    """Write ``obj`` to ``path`` as an official (Python 2 era) pickle would be written."""
    path = Path(path)
    with open(path, "wb") as fh:
        _LegacyPickler(fh, protocol=protocol, py2_strings=py2_strings).dump(obj)
    return path


def _save_legacy_npy_object(obj, path) -> Path:
    """A ``.npy`` holding a 0-d object array (e.g. a dict), as ``numpy.save`` under Python 2."""
    arr = np.empty((), dtype=object)
    arr[()] = obj
    path = Path(path)
    with open(path, "wb") as fh:
        np.lib.format.write_array_header_1_0(fh, {"descr": "|O", "fortran_order": False, "shape": ()})
        _LegacyPickler(fh, protocol=2, py2_strings=True).dump(arr)
    return path


def _ch(arr):
    import chumpy  # chumpy-fixed; only needed when writing files that hold a Ch

    return chumpy.Ch(np.asarray(arr))


def _object0(obj) -> np.ndarray:
    arr = np.empty((), dtype=object)
    arr[()] = obj
    return arr


def _npz(path: Path, data: dict) -> Path:
    """An uncompressed ``.npz`` like ``numpy.savez`` writes, but any key allowed (the official
    SMPL-X archives hold an ``allow_pickle`` entry, which today's ``savez`` would swallow)."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_STORED, allowZip64=True) as zf:
        for key, val in data.items():
            with zf.open(key + ".npy", "w", force_zip64=True) as fh:
                np.lib.format.write_array(fh, np.asanyarray(val), allow_pickle=True)
    return path


def _dense(x):
    return x.toarray() if sp.issparse(x) else np.asarray(x)
