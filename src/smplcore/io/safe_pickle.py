"""An unpickler that can build arrays and sparse matrices, and nothing else.

Official SMPL-family ``.pkl`` files are Python 2 pickles holding NumPy arrays, ``scipy.sparse``
matrices and ``chumpy`` objects. ``pickle.load`` on such a file would import chumpy and could run
any callable the file names. :func:`safe_load` instead runs the pickle through its own opcode
handlers (the pure-Python unpickler's, with every opcode that calls, instantiates or sets state
replaced):

* globals resolve through an allow-list to *recipes*, never to NumPy itself: ``numpy.dtype`` gives a
  :class:`DtypeRecipe` that accepts only plain numeric, bool and string type strings and reads
  nothing but the byte order and string length from its pickled state (no flags, fields or
  sub-arrays: a file cannot forge an object, void or structured dtype); ``_reconstruct``,
  ``_frombuffer`` and ``scalar`` build arrays with :func:`numpy.frombuffer` from a validated dtype, a
  validated shape and a byte string of exactly the right length. Object arrays are rebuilt from
  the unpickled Python values, never from bytes;
* ``BUILD`` (set an object's state) works only on those recipes and on stand-ins for chumpy and
  scipy.sparse classes that record their state; anything else - a function, a dtype - is refused;
* ``REDUCE`` and ``NEWOBJ`` call only the allow-listed recipes, stand-ins and a few builtins whose
  arguments are checked (``bytes(10**10)`` is refused); only the codecs real files use are allowed;
* every allocation is charged to a :class:`~smplcore.io.budgets.LoadBudget`, reads never ask for
  more bytes than the input has left, tuples nest at most ``MAX_NESTING`` deep, and values reused
  through the memo are shared, never copied.

Anything else raises :class:`UnsafePickleError` before it is called. :func:`materialize` turns the
recipes and stand-ins into plain NumPy arrays and real ``scipy.sparse`` matrices.
"""

from __future__ import annotations

import io
import pickle
import struct
from collections.abc import Callable
from typing import IO, Any, ClassVar

import numpy as np

from smplcore.errors import ModelFileError
from smplcore.io.budgets import (
    ALLOWED_CODECS,
    MAX_GLOBAL_NAME,
    MAX_NESTING,
    LoadBudget,
)
from smplcore.io.pickle_recipes import (
    ArrayRecipe,
    ChumpyObject,
    DtypeRecipe,
    NdarrayName,
    Recorded,
    SparseMatrix,
    UnsafePickleError,
    as_bytes,
    brief,
    build_array,
    materialize,
)

__all__ = ["ChumpyObject", "SparseMatrix", "UnsafePickleError", "materialize", "safe_load"]


class _BoundedReader:
    """A file wrapper whose reads never ask for more than the bytes left (no huge pre-allocation)."""

    def __init__(self, fh: IO[bytes], limit: int) -> None:
        self.fh, self.left = fh, int(limit)

    def read(self, n: int = -1) -> bytes:
        if n is None or n < 0:
            n = self.left
        if n > self.left:
            raise EOFError(f"the pickle asks for {n:,} bytes but only {self.left:,} remain")
        data = self.fh.read(n)
        self.left -= len(data)
        return data

    def readline(self) -> bytes:
        line = self.fh.readline(max(self.left, 0))
        self.left -= len(line)
        return line


_BUILTIN_CONTAINERS = {"set": set, "frozenset": frozenset, "list": list, "tuple": tuple, "dict": dict}
_BUILTIN_SCALARS = {"int": int, "float": float, "complex": complex, "bool": bool}
_BUILTIN_NAMES = set(_BUILTIN_CONTAINERS) | set(_BUILTIN_SCALARS) | {"str", "bytes", "bytearray", "object"}
_SPARSE_CLASSES = {"csc_matrix", "csr_matrix", "coo_matrix", "csc_array", "csr_array", "coo_array"}
_SHORT_TEXT = 64


def _check_codec(encoding: Any, errors: Any = "strict") -> str:
    if not isinstance(encoding, str) or encoding.lower() not in ALLOWED_CODECS:
        raise UnsafePickleError(f"codec {brief(encoding)} is not allowed (only latin1, ascii, utf-8)")
    if errors != "strict":
        raise UnsafePickleError(f"codec error handler {brief(errors)} is not allowed")
    return encoding


class _SafeUnpickler(pickle._Unpickler):
    # The pure-Python unpickler's internals that the opcode handlers below use, declared for the type
    # checker (typeshed leaves them out); pickle._Unpickler sets or defines every one of them.
    stack: list[Any]
    append: Callable[[Any], None]
    read: Callable[[int], bytes]
    readline: Callable[[], bytes]
    pop_mark: Callable[[], list[Any]]
    # the opcode table: its handlers take this class (typeshed says pickle.Unpickler)
    dispatch: ClassVar[dict[int, Callable[[Any], None]]] = pickle._Unpickler.dispatch.copy()

    def __init__(self, file: _BoundedReader, budget: LoadBudget) -> None:
        super().__init__(file, encoding="latin1", fix_imports=False)
        self.budget = budget
        self._stand_ins: dict[tuple[str, str], type] = {}
        self._tuples: dict[int, tuple[Any, int]] = {}  # id -> (tuple, nesting); holding it keeps ids unique
        self._functions = {
            "dtype": self._dtype,
            "_reconstruct": self._reconstruct,
            "scalar": self._scalar,
            "_frombuffer": self._frombuffer,
            "_reconstructor": self._reconstructor,
            "encode": self._encode,
        }
        self._callable_ids = {id(f) for f in self._functions.values()}
        self._builtins = {name: self._builtin_caller(name) for name in _BUILTIN_NAMES}
        self._callable_ids |= {id(f) for f in self._builtins.values()}

    # -- globals -------------------------------------------------------------------------------
    def find_class(self, module: str, name: str) -> Any:
        if len(module) > MAX_GLOBAL_NAME or len(name) > MAX_GLOBAL_NAME:
            raise UnsafePickleError("the pickle names a global with an over-long name")
        if module == "numpy" and name == "ndarray":
            return NdarrayName
        if (module, name) == ("numpy", "dtype"):
            return self._functions["dtype"]
        if module in ("numpy.core.multiarray", "numpy._core.multiarray") and name in ("_reconstruct", "scalar"):
            return self._functions[name]
        if module in ("numpy.core.numeric", "numpy._core.numeric") and name == "_frombuffer":
            return self._functions[name]
        if module in ("builtins", "__builtin__") and name in _BUILTIN_NAMES:
            return object if name == "object" else self._builtins[name]
        if module in ("copyreg", "copy_reg") and name == "_reconstructor":
            return self._functions[name]
        if module == "_codecs" and name == "encode":
            return self._functions[name]
        if module == "chumpy" or module.startswith("chumpy."):
            return self._stand_in(ChumpyObject, module, name)
        if module.startswith("scipy.sparse") and name in _SPARSE_CLASSES:
            return self._stand_in(SparseMatrix, module, name)
        raise UnsafePickleError(f"the pickle asks for {module}.{name}, which a model file may not use")

    def _stand_in(self, base: type, module: str, name: str) -> type:
        key = (module, name)
        if key not in self._stand_ins:
            self.budget.charge(2048, "a stand-in class")
            self._stand_ins[key] = type(name, (base,), {"module": module, "name": name})
        return self._stand_ins[key]

    # -- allow-listed callables ------------------------------------------------------------------
    def _dtype(self, type_str: Any, align: Any = False, copy: Any = True) -> DtypeRecipe:
        return DtypeRecipe(type_str)

    def _reconstruct(self, cls: Any, shape: Any = (0,), typecode: Any = b"b") -> ArrayRecipe:
        if cls is not NdarrayName:
            raise UnsafePickleError(f"_reconstruct of {getattr(cls, '__name__', type(cls).__name__)} is not allowed")
        return ArrayRecipe(self.budget)

    def _scalar(self, dtype: Any, data: Any = None) -> Any:
        if not isinstance(dtype, DtypeRecipe) or dtype.is_object:
            raise UnsafePickleError("numpy scalars must have a plain numeric, bool or string dtype")
        real = dtype.resolve()
        self.budget.charge(real.itemsize, "a numpy scalar")
        raw = as_bytes(data, "scalar data")
        if len(raw) != real.itemsize:
            raise pickle.UnpicklingError(f"a {real} scalar needs {real.itemsize} bytes, found {len(raw)}")
        return np.frombuffer(raw, dtype=real, count=1)[0]

    def _frombuffer(self, buf: Any, dtype: Any, shape: Any, order: Any = "C") -> Any:
        if order not in ("C", "F"):
            raise UnsafePickleError(f"array order {brief(order)} is not allowed")
        if isinstance(dtype, DtypeRecipe) and dtype.is_object:
            raise UnsafePickleError("object arrays cannot be built from a buffer")
        if isinstance(buf, str):
            raise UnsafePickleError("_frombuffer needs bytes")
        return build_array(self.budget, dtype, shape, buf, order)

    def _reconstructor(self, cls: Any, base: Any = object, state: Any = None) -> Any:
        """Python 2's ``copy_reg._reconstructor``, limited to our stand-ins on ``object``."""
        if isinstance(cls, type) and issubclass(cls, Recorded) and base is object and state is None:
            return cls()
        raise UnsafePickleError(f"copy_reg._reconstructor of {getattr(cls, '__name__', type(cls).__name__)}")

    def _encode(self, obj: Any, encoding: Any = "utf-8", errors: Any = "strict") -> bytes:
        """``_codecs.encode`` as Python 3 pickles of bytes use it (text to bytes only)."""
        if not isinstance(obj, str):
            raise UnsafePickleError("_codecs.encode on a non-string is not allowed")
        _check_codec(encoding, errors)
        self.budget.charge(4 * len(obj), "_codecs.encode")
        return obj.encode(encoding)

    def _builtin_caller(self, name: str) -> Any:
        def call(*args: Any) -> Any:
            return self._call_builtin(name, args)

        call.__name__ = name
        return call

    def _call_builtin(self, name: str, args: tuple) -> Any:
        if name in _BUILTIN_CONTAINERS:
            if len(args) > 1 or (args and type(args[0]) not in (list, tuple, set, frozenset, dict)):
                raise UnsafePickleError(f"builtins.{name} may only copy a list, tuple, set or dict")
            self.budget.charge(64 + 16 * (len(args[0]) if args else 0), f"builtins.{name}")
            return _BUILTIN_CONTAINERS[name](*args)
        if name in _BUILTIN_SCALARS:
            ok = len(args) <= 2 and all(
                type(a) in (int, float, bool) or (type(a) is str and len(a) <= _SHORT_TEXT) for a in args
            )
            if not ok or any(type(a) is int and a.bit_length() > 4096 for a in args):
                raise UnsafePickleError(f"builtins.{name} may only convert short numbers and text")
            return _BUILTIN_SCALARS[name](*args)
        if name in ("str", "bytes", "bytearray"):
            text_type = bytes if name == "str" else str
            if not args:
                value: Any = {"str": str, "bytes": bytes, "bytearray": bytearray}[name]()
            elif len(args) == 1 and type(args[0]) in ((str, int, float) if name == "str" else (bytes, bytearray)):
                self.budget.charge(64 + len(str(args[0]) if name == "str" else args[0]), f"builtins.{name}")
                value = {"str": str, "bytes": bytes, "bytearray": bytearray}[name](args[0])
            elif len(args) in (2, 3) and type(args[0]) is text_type:
                _check_codec(*args[1:])
                self.budget.charge(64 + 4 * len(args[0]), f"builtins.{name}")
                value = {"str": str, "bytes": bytes, "bytearray": bytearray}[name](*args)
            else:
                raise UnsafePickleError(f"builtins.{name} with these arguments is not allowed")
            return value
        raise UnsafePickleError(f"calling builtins.{name} is not allowed")

    def _call(self, func: Any, args: Any) -> Any:
        if not isinstance(args, tuple):
            raise pickle.UnpicklingError("REDUCE needs a tuple of arguments")
        if id(func) in self._callable_ids:
            result = func(*args)
        elif isinstance(func, type) and issubclass(func, Recorded):
            self.budget.charge(256, "a stand-in object")
            result = func(*args)
        else:
            raise UnsafePickleError(f"calling {getattr(func, '__name__', type(func).__name__)} is not allowed")
        return self._nested(result) if type(result) in (tuple, frozenset) else result

    def _instantiate(self, cls: Any) -> Any:
        if isinstance(cls, type) and issubclass(cls, Recorded):
            self.budget.charge(256, "a stand-in object")
            return cls()
        raise UnsafePickleError(f"creating a {getattr(cls, '__name__', type(cls).__name__)} is not allowed")

    def _nested(self, value: Any) -> Any:
        """Register a new tuple / frozenset with its nesting depth; refuse past MAX_NESTING."""
        self._depth(value, 0)
        return value

    def _depth(self, value: Any, level: int) -> int:
        entry = self._tuples.get(id(value))
        if entry is not None and entry[0] is value:
            return entry[1]
        if level > MAX_NESTING:
            raise UnsafePickleError(f"tuples nested more than {MAX_NESTING} deep")
        depth = 1 + max((self._depth(v, level + 1) for v in value if type(v) in (tuple, frozenset)), default=0)
        if depth > MAX_NESTING:
            raise UnsafePickleError(f"tuples nested more than {MAX_NESTING} deep")
        self._tuples[id(value)] = (value, depth)
        return depth

    # -- opcodes that call, instantiate, set state or build containers ---------------------------
    def load_reduce(self) -> None:
        args = self.stack.pop()
        self.stack[-1] = self._call(self.stack[-1], args)

    def load_newobj(self) -> None:
        self.stack.pop()  # arguments: stand-ins take none
        self.stack[-1] = self._instantiate(self.stack[-1])

    def load_newobj_ex(self) -> None:
        self.stack.pop()
        self.stack.pop()
        self.stack[-1] = self._instantiate(self.stack[-1])

    def load_inst(self) -> None:
        module = self.readline()[:-1].decode("ascii")
        name = self.readline()[:-1].decode("ascii")
        cls = self.find_class(module, name)
        self.pop_mark()
        self.append(self._instantiate(cls))

    def load_obj(self) -> None:
        args = self.pop_mark()
        if not args:
            raise pickle.UnpicklingError("OBJ without a class")
        value = self._instantiate(args[0])
        self.append(value)

    def load_build(self) -> None:
        state = self.stack.pop()
        inst = self.stack[-1]
        if not isinstance(inst, (Recorded, DtypeRecipe, ArrayRecipe)):
            raise UnsafePickleError(f"setting the state of a {type(inst).__name__} is not allowed")
        inst.__setstate__(state)

    def load_ext(self) -> None:
        raise UnsafePickleError("pickle extension codes (copyreg registry) are not allowed")

    def persistent_load(self, pid: Any) -> Any:
        raise UnsafePickleError("persistent ids are not allowed")

    def load_setitem(self) -> None:
        value = self.stack.pop()
        key = self.stack.pop()
        self._target(dict)[key] = value

    def load_setitems(self) -> None:
        items = self.pop_mark()
        target = self._target(dict)
        for i in range(0, len(items) - 1, 2):
            target[items[i]] = items[i + 1]

    def load_append(self) -> None:
        value = self.stack.pop()
        self._target(list).append(value)

    def load_appends(self) -> None:
        items = self.pop_mark()
        self._target(list).extend(items)

    def load_additems(self) -> None:
        items = self.pop_mark()
        self._target(set).update(items)

    def _target(self, kind: type) -> Any:
        target = self.stack[-1]
        if type(target) is not kind:
            raise pickle.UnpicklingError(f"cannot add items to a {type(target).__name__}")
        return target

    def load_bytearray8(self) -> None:
        """As pickle's, but the declared length is charged before ``bytearray(length)`` is allocated."""
        (length,) = struct.unpack("<Q", self.read(8))
        self.budget.charge(length, "a BYTEARRAY8 of the declared length")
        data = self.read(length)
        if len(data) != length:
            raise pickle.UnpicklingError(f"BYTEARRAY8 declares {length} bytes, found {len(data)}")
        self.append(bytearray(data))

    def load_tuple(self) -> None:
        value = self._nested(tuple(self.pop_mark()))  # pop_mark replaces self.append: call it first
        self.append(value)

    def load_empty_tuple(self) -> None:
        self.append(())

    def load_tuple1(self) -> None:
        self.stack[-1] = self._nested((self.stack[-1],))

    def load_tuple2(self) -> None:
        self.stack[-2:] = [self._nested((self.stack[-2], self.stack[-1]))]

    def load_tuple3(self) -> None:
        self.stack[-3:] = [self._nested((self.stack[-3], self.stack[-2], self.stack[-1]))]

    def load_frozenset(self) -> None:
        value = self._nested(frozenset(self.pop_mark()))
        self.append(value)

    for _op, _method in (
        (pickle.REDUCE, load_reduce),
        (pickle.NEWOBJ, load_newobj),
        (pickle.NEWOBJ_EX, load_newobj_ex),
        (pickle.INST, load_inst),
        (pickle.OBJ, load_obj),
        (pickle.BUILD, load_build),
        (pickle.EXT1, load_ext),
        (pickle.EXT2, load_ext),
        (pickle.EXT4, load_ext),
        (pickle.SETITEM, load_setitem),
        (pickle.SETITEMS, load_setitems),
        (pickle.APPEND, load_append),
        (pickle.APPENDS, load_appends),
        (pickle.ADDITEMS, load_additems),
        (pickle.TUPLE, load_tuple),
        (pickle.EMPTY_TUPLE, load_empty_tuple),
        (pickle.TUPLE1, load_tuple1),
        (pickle.TUPLE2, load_tuple2),
        (pickle.TUPLE3, load_tuple3),
        (pickle.FROZENSET, load_frozenset),
        (pickle.BYTEARRAY8, load_bytearray8),
    ):
        dispatch[_op[0]] = _method
    del _op, _method


def safe_load(file: IO[bytes] | bytes, budget: LoadBudget | None = None, *, limit: int | None = None) -> Any:
    """Unpickle ``file`` (a binary file object or bytes) through the allow-list.

    Parameters
    ----------
    file : bytes, or a binary file positioned at the pickle.
    budget : what the unpickling may allocate (default: a budget for an input of ``limit`` bytes).
    limit : bytes the pickle may read (default: the rest of ``file``).

    Returns the unpickled object with chumpy and scipy.sparse stand-ins already materialized into
    NumPy arrays and ``scipy.sparse`` matrices.

    Raises
    ------
    UnsafePickleError
        The pickle names a global outside the allow-list, or asks to call or set state on anything
        but our recipes and stand-ins (nothing was called).
    ModelFileError
        The pickle would allocate more than ``budget`` allows.
    pickle.UnpicklingError
        Any other damage (truncated data, invalid opcodes or values, ...).
    """
    if isinstance(file, (bytes, bytearray, memoryview)):
        file = io.BytesIO(file)
    if limit is None:
        start = file.tell()
        limit = file.seek(0, io.SEEK_END) - start
        file.seek(start)
    if budget is None:
        budget = LoadBudget("<pickle>", limit)
    try:
        data = _SafeUnpickler(_BoundedReader(file, limit), budget).load()
        return materialize(data, budget)
    except (UnsafePickleError, ModelFileError):
        raise
    except pickle.UnpicklingError as exc:
        raise pickle.UnpicklingError(str(exc)) from None
    except Exception as exc:  # noqa: BLE001 - EOF, struct, Type/Value/Overflow/Recursion/MemoryError, ...
        raise pickle.UnpicklingError(f"{type(exc).__name__}: {exc}") from None
