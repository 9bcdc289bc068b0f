"""What allow-listed pickle globals build: recipes for dtypes and arrays, stand-ins for foreign classes.

Nothing here hands file-controlled values to NumPy unchecked: a :class:`DtypeRecipe` accepts only
plain numeric, bool and string type strings and takes nothing but the byte order and string length
from its pickled state; arrays are made with :func:`numpy.frombuffer` from a resolved recipe, a shape
checked against the budget, and exactly ``prod(shape) * itemsize`` bytes. Object arrays are kept as
lists of unpickled Python values (:class:`ObjectArray`), never built from bytes.
"""

from __future__ import annotations

import pickle
import re
from typing import Any

import numpy as np

from smplcore.errors import SmplcoreError
from smplcore.io.budgets import MAX_LIST_NODES, MAX_NESTING, LoadBudget, element_count, nested_list_size
from smplcore.io.sparse_values import sparse_value


class UnsafePickleError(SmplcoreError, pickle.UnpicklingError):
    """The pickle names a global outside the allow-list, or asks to call or set state on something
    it may not."""


def brief(value: Any) -> str:
    """A short description of a file-controlled value for messages: text is cut, anything else is
    named by type (``str()`` of a list shared through the memo could take exponential time)."""
    return repr(value[:40]) if isinstance(value, str) else f"a {type(value).__name__}"


class Recorded:
    """Stand-in for an allow-listed foreign class: records the state it is given, runs nothing."""

    module = ""
    name = ""

    def __init__(self, *args: Any) -> None:
        self.args = args
        self.state: Any = None

    def __setstate__(self, state: Any) -> None:
        self.state = state


class ChumpyObject(Recorded):
    """A chumpy object; its value is the array under ``x`` in its state."""


class SparseMatrix(Recorded):
    """A scipy.sparse matrix; rebuilt from ``data``/``indices``/``indptr`` (or ``row``/``col``)."""


class NdarrayName:
    """What ``numpy.ndarray`` resolves to: only a marker passed to ``_reconstruct``."""


_DTYPE_STRINGS = re.compile(r"(b1|[iu][1248]|f[248]|c(8|16)|[SU][0-9]{1,9}|O[48])\Z")
_BYTE_ORDERS = ("<", ">", "|", "=")
# The flags numpy writes for each kind: none for plain types, NPY_NEEDS_INIT for unicode, the
# object bits for "O". Any other value would ask for item semantics we never build.
_DTYPE_FLAGS = {"U": (0, 8), "O": (63,)}


class DtypeRecipe:
    """A dtype named by a pickle: a whitelisted type string plus byte order / string length."""

    def __init__(self, type_str: str) -> None:
        if not isinstance(type_str, str) or not _DTYPE_STRINGS.match(type_str):
            raise UnsafePickleError(f"dtype {brief(type_str)} is not a plain numeric, bool or string type")
        self.type_str = type_str
        self.byteorder = "="
        self.elsize = -1

    def __setstate__(self, state: Any) -> None:
        """Read the byte order and string length from numpy's state tuple; refuse anything else."""
        if not isinstance(state, tuple) or len(state) not in (8, 9) or state[0] not in (3, 4):
            raise UnsafePickleError("a dtype's pickled state is not numpy's plain (version 3) layout")
        _, byteorder, subdescr, names, fields, elsize, _alignment, _flags = state[:8]
        if len(state) == 9 and state[8] is not None:
            raise UnsafePickleError("dtype metadata is not allowed")
        if subdescr is not None or names is not None or fields is not None:
            raise UnsafePickleError("structured and sub-array dtypes are not allowed")
        if byteorder not in _BYTE_ORDERS or type(elsize) is not int or type(_flags) is not int:
            raise UnsafePickleError(f"invalid dtype state (byte order {byteorder!r}, size {elsize!r})")
        allowed = _DTYPE_FLAGS.get(self.type_str[0], (0,))
        if _flags not in allowed:
            raise UnsafePickleError(f"dtype {self.type_str} with flags {_flags} (numpy writes {allowed[-1]})")
        self.byteorder, self.elsize = byteorder, elsize

    @property
    def is_object(self) -> bool:
        return self.type_str[0] == "O"

    def resolve(self) -> np.dtype:
        """The real dtype (never an object, void or structured one: see :attr:`is_object`)."""
        kind = self.type_str[0]
        if kind == "O":
            raise UnsafePickleError("an object dtype cannot be used here")
        if kind in "SU" and self.elsize != -1:
            per_char = 4 if kind == "U" else 1
            if self.elsize <= 0 or self.elsize % per_char or self.elsize > (1 << 20):
                raise UnsafePickleError(f"invalid string dtype size {self.elsize}")
            dtype = np.dtype(f"{kind}{self.elsize // per_char}")
        else:
            dtype = np.dtype(self.type_str)
            if self.elsize not in (-1, dtype.itemsize):
                raise UnsafePickleError(f"dtype {self.type_str} with item size {self.elsize}")
        if self.byteorder in "<>" and dtype.itemsize > 1 and kind != "S":
            dtype = dtype.newbyteorder("<" if self.byteorder == "<" else ">")
        if dtype.itemsize == 0:
            raise UnsafePickleError(f"zero-size dtype {dtype}")
        return dtype


class ArrayRecipe:
    """``_reconstruct``'s result: becomes an array when ``BUILD`` gives it shape, dtype and data."""

    def __init__(self, budget: LoadBudget) -> None:
        self.budget = budget
        self.value: Any = None

    def __setstate__(self, state: Any) -> None:
        if not isinstance(state, tuple) or len(state) not in (4, 5):
            raise UnsafePickleError("an ndarray's pickled state is not (version, shape, dtype, fortran, data)")
        shape, dtype, fortran, data = state[-4:]
        if fortran not in (0, 1):
            raise UnsafePickleError("an ndarray's fortran flag must be True or False")
        self.value = build_array(self.budget, dtype, shape, data, "F" if fortran else "C")


class ObjectArray:
    """An object array: Python values from the pickle, made into an ndarray by :func:`materialize`."""

    def __init__(self, shape: tuple[int, ...], items: list, order: str) -> None:
        self.shape, self.items, self.order = shape, items, order


def as_bytes(data: Any, what: str) -> bytes:
    if isinstance(data, str):
        return data.encode("latin1")  # Python 2 str read with encoding="latin1"
    if isinstance(data, (bytes, bytearray, memoryview)):
        return bytes(data)
    raise UnsafePickleError(f"{what}: expected bytes, found {type(data).__name__}")


def build_array(budget: LoadBudget, dtype: Any, shape: Any, data: Any, order: str) -> Any:
    """An array from a validated dtype, shape and exactly ``prod(shape) * itemsize`` bytes."""
    if not isinstance(dtype, DtypeRecipe):
        raise UnsafePickleError(f"an array's dtype must come from numpy.dtype, found {type(dtype).__name__}")
    shape = budget.check_shape(tuple(shape) if isinstance(shape, (tuple, list)) else shape, "pickled array")
    count = element_count(shape)
    if dtype.is_object:
        if not isinstance(data, list) or len(data) != count:
            raise UnsafePickleError(f"an object array of shape {shape} needs a list of {count} values")
        budget.charge(8 * count, "pickled object array")
        return ObjectArray(shape, data, order)
    real = dtype.resolve()
    nbytes = count * real.itemsize
    budget.charge(nbytes * (2 if isinstance(data, str) else 1), "pickled array")
    raw = as_bytes(data, "array data")
    if len(raw) != nbytes:
        raise pickle.UnpicklingError(f"array of shape {shape} and dtype {real} needs {nbytes} bytes, found {len(raw)}")
    return np.frombuffer(raw, dtype=real, count=count).reshape(shape, order="F" if order == "F" else "C")


def materialize(obj: Any, budget: LoadBudget | None = None) -> Any:
    """Replace recipes and stand-ins inside ``obj`` (dicts, lists, tuples, sets) by arrays and
    sparse matrices. Values reached twice are built once and shared; nesting is limited."""
    return _Materializer(budget or LoadBudget("<pickle>", 0)).run(obj, 0)


class _Materializer:
    def __init__(self, budget: LoadBudget) -> None:
        self.budget = budget
        self.done: dict[int, Any] = {}
        self.keep: list[Any] = []  # keeps inputs alive so their ids stay unique

    def run(self, obj: Any, depth: int) -> Any:
        kind = type(obj)
        if kind in (int, float, str, bytes, bool, complex, type(None), np.ndarray):
            return obj
        if depth > MAX_NESTING:
            raise pickle.UnpicklingError(f"values nested more than {MAX_NESTING} deep")
        if id(obj) in self.done:
            return self.done[id(obj)]
        self.keep.append(obj)
        if kind is list:
            out: Any = []
            self.done[id(obj)] = out
            out.extend(self.run(v, depth + 1) for v in obj)
        elif kind is dict:
            out = {}
            self.done[id(obj)] = out
            for key, value in obj.items():
                out[key] = self.run(value, depth + 1)
        elif kind in (tuple, set, frozenset):
            out = kind(self.run(v, depth + 1) for v in obj)
        elif isinstance(obj, ArrayRecipe):
            if obj.value is None:
                raise pickle.UnpicklingError("an ndarray without its data (no BUILD)")
            out = self.run(obj.value, depth + 1)
        elif isinstance(obj, ObjectArray):
            out = np.empty(len(obj.items), dtype=object)
            for i, item in enumerate(obj.items):
                out[i] = self.run(item, depth + 1)
            out = out.reshape(obj.shape, order=obj.order)
        elif isinstance(obj, DtypeRecipe):
            out = np.dtype(object) if obj.is_object else obj.resolve()
        elif isinstance(obj, ChumpyObject):
            out = self._chumpy_value(obj, depth)
        elif isinstance(obj, SparseMatrix):
            state = obj.state if isinstance(obj.state, dict) else {}
            state = {k: self.run(v, depth + 1) for k, v in state.items() if isinstance(k, str)}
            out = sparse_value(obj.name, state, self.budget)
        else:
            out = obj
        self.done[id(obj)] = out
        return out

    def _chumpy_value(self, obj: ChumpyObject, depth: int) -> np.ndarray:
        state = obj.state if isinstance(obj.state, dict) else {}
        if "x" not in state:
            raise pickle.UnpicklingError(
                f"chumpy object {obj.module}.{obj.name} has no stored value 'x' "
                "(only plain chumpy arrays can be read without chumpy)"
            )
        value = self.run(state["x"], depth + 1)
        if not isinstance(value, np.ndarray):
            if not isinstance(value, (list, tuple, int, float)):
                raise pickle.UnpicklingError(f"chumpy value 'x' is a {type(value).__name__}, not an array")
            size = nested_list_size(value)
            if size > MAX_LIST_NODES:
                raise pickle.UnpicklingError(
                    f"chumpy value 'x' is a nested list of more than {MAX_LIST_NODES:,} entries"
                )
            self.budget.charge(8 * size, "chumpy x")
            value = np.asarray(value)
        if value.dtype == object:
            raise pickle.UnpicklingError("chumpy value 'x' holds Python objects")
        return value
