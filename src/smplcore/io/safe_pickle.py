"""An unpickler that can build arrays and sparse matrices, and nothing else.

Official SMPL-family ``.pkl`` files are Python 2 pickles holding NumPy arrays, ``scipy.sparse``
matrices and ``chumpy`` objects. ``pickle.load`` on such a file would import chumpy and could run
any callable the file names. :func:`safe_load` instead resolves every global the file names through
an allow-list: NumPy's array and dtype constructors, a few harmless builtins, and stand-ins for
chumpy and scipy.sparse classes that only record their state. Anything else raises
:class:`UnsafePickleError` before it is called. The stand-ins are turned into plain NumPy arrays
and real ``scipy.sparse`` matrices afterwards by :func:`materialize`.
"""

from __future__ import annotations

import codecs
import io
import pickle
from typing import Any, BinaryIO

import numpy as np


class UnsafePickleError(pickle.UnpicklingError):
    """The pickle names a global outside the allow-list."""


class _Recorded:
    """Stand-in for an allow-listed foreign class: records the state it is given, runs nothing."""

    module = ""
    name = ""
    args: tuple = ()
    state: Any = None

    def __init__(self, *args: Any) -> None:
        self.args = args
        self.state: Any = None

    def __setstate__(self, state: Any) -> None:
        self.state = state


class ChumpyObject(_Recorded):
    """A chumpy object; its value is the array under ``x`` in its state."""


class SparseMatrix(_Recorded):
    """A scipy.sparse matrix; rebuilt from ``data``/``indices``/``indptr`` (or ``row``/``col``)."""


def _stand_in(base: type, module: str, name: str) -> type:
    return type(name, (base,), {"module": module, "name": name})


def _reconstructor(cls: type, base: type, state: Any) -> Any:
    """Python 2's ``copy_reg._reconstructor``, limited to our stand-ins and ``object``."""
    if isinstance(cls, type) and issubclass(cls, _Recorded):
        return cls()
    raise UnsafePickleError(f"copy_reg._reconstructor of {cls!r} is not allowed")


def _encode(obj: str, encoding: str = "latin1") -> bytes:
    """``_codecs.encode`` as Python 3 pickles of bytes use it (text to bytes only)."""
    if not isinstance(obj, str):
        raise UnsafePickleError("_codecs.encode on a non-string is not allowed")
    return codecs.encode(obj, encoding)


_NUMPY_GLOBALS = {
    ("numpy", "ndarray"): np.ndarray,
    ("numpy", "dtype"): np.dtype,
}
for _mod in ("numpy.core.multiarray", "numpy._core.multiarray"):
    _NUMPY_GLOBALS[(_mod, "_reconstruct")] = np._core.multiarray._reconstruct
    _NUMPY_GLOBALS[(_mod, "scalar")] = np._core.multiarray.scalar
for _mod in ("numpy.core.numeric", "numpy._core.numeric"):
    _NUMPY_GLOBALS[(_mod, "_frombuffer")] = np._core.numeric._frombuffer

_BUILTINS = {
    name: getattr(__import__("builtins"), name)
    for name in (
        "set",
        "frozenset",
        "list",
        "dict",
        "tuple",
        "int",
        "float",
        "complex",
        "bytes",
        "bytearray",
        "str",
        "bool",
        "object",
    )
}

_SPARSE_CLASSES = {"csc_matrix", "csr_matrix", "coo_matrix", "csc_array", "csr_array", "coo_array"}


class _AllowListUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str) -> Any:
        if (module, name) in _NUMPY_GLOBALS:
            return _NUMPY_GLOBALS[(module, name)]
        if module in ("builtins", "__builtin__") and name in _BUILTINS:
            return _BUILTINS[name]
        if module in ("copyreg", "copy_reg") and name == "_reconstructor":
            return _reconstructor
        if module == "_codecs" and name == "encode":
            return _encode
        if module == "chumpy" or module.startswith("chumpy."):
            return _stand_in(ChumpyObject, module, name)
        if module.startswith("scipy.sparse") and name in _SPARSE_CLASSES:
            return _stand_in(SparseMatrix, module, name)
        raise UnsafePickleError(f"the pickle asks for {module}.{name}, which a model file may not use")


def safe_load(file: BinaryIO | bytes) -> Any:
    """Unpickle ``file`` (a binary file object or bytes) through the allow-list.

    Returns the unpickled object with chumpy and scipy.sparse stand-ins already materialized into
    NumPy arrays and ``scipy.sparse`` matrices.

    Raises
    ------
    UnsafePickleError
        The pickle names a global outside the allow-list (nothing was called).
    pickle.UnpicklingError, EOFError, ValueError
        The data is not a valid pickle (e.g. truncated).
    """
    if isinstance(file, (bytes, bytearray)):
        file = io.BytesIO(file)
    data = _AllowListUnpickler(file, encoding="latin1", fix_imports=True).load()
    return materialize(data)


def materialize(obj: Any) -> Any:
    """Replace stand-ins inside ``obj`` (dicts, lists, tuples) by arrays and sparse matrices."""
    if isinstance(obj, ChumpyObject):
        return _chumpy_value(obj)
    if isinstance(obj, SparseMatrix):
        return _sparse_value(obj)
    if isinstance(obj, dict):
        return {key: materialize(value) for key, value in obj.items()}
    if isinstance(obj, (list, tuple)):
        return type(obj)(materialize(value) for value in obj)
    return obj


def _chumpy_value(obj: ChumpyObject) -> np.ndarray:
    state = obj.state if isinstance(obj.state, dict) else {}
    if "x" not in state:
        raise pickle.UnpicklingError(
            f"chumpy object {obj.module}.{obj.name} has no stored value 'x' "
            "(only plain chumpy arrays can be read without chumpy)"
        )
    return np.asarray(materialize(state["x"]))


def _sparse_value(obj: SparseMatrix) -> Any:
    import scipy.sparse as sp

    state = obj.state if isinstance(obj.state, dict) else {}
    shape = tuple(state.get("_shape") or state.get("shape") or ())
    fmt = obj.name[:3]
    try:
        if fmt == "coo":
            return sp.coo_matrix((state["data"], (state["row"], state["col"])), shape=shape)
        cls = sp.csc_matrix if fmt == "csc" else sp.csr_matrix
        return cls((state["data"], state["indices"], state["indptr"]), shape=shape)
    except (KeyError, ValueError, TypeError) as exc:
        raise pickle.UnpicklingError(f"invalid {obj.name} in the pickle: {exc}") from exc
