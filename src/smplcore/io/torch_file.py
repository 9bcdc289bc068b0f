"""PyTorch checkpoints (``torch.save``'s zip format) read without torch and without running anything.

A ``.pt``/``.ckpt`` file written by ``torch.save`` (torch ≥ 1.6) is a zip archive: ``<name>/data.pkl``, a
pickle whose tensors point through *persistent ids* ``('storage', torch.FloatStorage, key, location,
numel)`` at raw little-endian members ``<name>/data/<key>``, and rebuild themselves with
``torch._utils._rebuild_tensor_v2(storage, offset, size, stride, ...)``. :func:`load_torch_file` runs
that pickle through smplcore's allow-list unpickler (:mod:`smplcore.io.safe_pickle`) extended with:

* the storage types and ``_rebuild_tensor_v2`` / ``_rebuild_parameter`` / ``_rebuild_from_type_v2``,
  resolved to NumPy: a tensor becomes a copy of its strided view of the storage's bytes, after the
  size, strides and offset are checked to stay inside the storage;
* ``collections.OrderedDict`` as a plain ``dict`` (its ``_metadata`` state is dropped);
* every other class or function the pickle names (a PyTorch-Lightning hyper-parameter object, an
  optimizer's class, ``torch.device``, ...) as an :class:`Opaque` placeholder: it records what the pickle
  gives it and is never constructed or called; asking it to be called gives another placeholder.

So nothing in the file runs, torch is not needed, and whatever a checkpoint carries besides its tensors
is kept only as inert placeholders. Every allocation is charged to the file's
:class:`~smplcore.io.budgets.LoadBudget`; failures are :class:`~smplcore.errors.ModelFileError` naming
the file (and the member).
"""

from __future__ import annotations

import io
import pickle
import re
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ModelFileError
from smplcore.io.budgets import MAX_DEFLATE_RATIO, MAX_GLOBAL_NAME, MAX_NDIM, LoadBudget, element_count
from smplcore.io.containers import _corrupt, open_regular
from smplcore.io.pickle_recipes import Recorded, UnsafePickleError, materialize
from smplcore.io.safe_pickle import _BoundedReader, _SafeUnpickler

__all__ = ["Opaque", "load_torch_file"]

#: torch's typed storage classes and the NumPy dtype of their elements (little-endian as written)
STORAGE_DTYPES = {
    "DoubleStorage": "<f8",
    "FloatStorage": "<f4",
    "HalfStorage": "<f2",
    "BFloat16Storage": "<u2",  # widened to float32 on reading
    "LongStorage": "<i8",
    "IntStorage": "<i4",
    "ShortStorage": "<i2",
    "CharStorage": "i1",
    "ByteStorage": "u1",
    "BoolStorage": "?",
}
#: members of a checkpoint (a Lightning checkpoint of a small network holds ~100: weights, optimizer states)
MAX_TORCH_MEMBERS = 4096
_ZIP_MAGIC = b"PK\x03\x04"
_KEY = re.compile(r"[A-Za-z0-9_.]{1,64}\Z")


class Opaque(Recorded):
    """An object of a class outside the allow-list (``module``, ``name``): never constructed, never called.

    ``args`` and ``state`` hold what the pickle passed (inert values); items a pickle adds to it (a dict
    or list subclass) are dropped.
    """

    def __repr__(self) -> str:
        return f"<opaque {self.module}.{self.name}>"


class StorageType:
    """What ``torch.FloatStorage`` (and the other typed storages) resolve to: a name and a dtype."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.dtype = np.dtype(STORAGE_DTYPES[name])


class Storage:
    """A storage's elements, (n,) NumPy array in the machine's byte order."""

    def __init__(self, values: np.ndarray) -> None:
        self.values = values


class _Archive:
    """The members of a torch zip checkpoint, read through the budget."""

    def __init__(self, path: Path, fh: Any, budget: LoadBudget) -> None:
        self.path, self.budget = path, budget
        end = zipfile._EndRecData(fh)  # type: ignore[attr-defined]  # private, counts entries before parsing
        if end is None:
            raise zipfile.BadZipFile("no end of central directory record")
        if end[zipfile._ECD_ENTRIES_TOTAL] > MAX_TORCH_MEMBERS:  # type: ignore[attr-defined]
            raise ModelFileError(path, f"the archive lists more than {MAX_TORCH_MEMBERS} members")
        fh.seek(0)
        self.zip = zipfile.ZipFile(fh)
        self.members = {info.filename: info for info in self.zip.infolist()}
        pickles = [name for name in self.members if name.count("/") == 1 and name.endswith("/data.pkl")]
        if len(pickles) != 1:
            raise ModelFileError(
                path, "not a PyTorch checkpoint: expected one '<name>/data.pkl' in the zip archive, found "
                f"{len(pickles)}"
            )  # fmt: skip
        self.prefix = pickles[0][: -len("data.pkl")]
        order = self.members.get(self.prefix + "byteorder")
        self.big_endian = order is not None and self.read(order.filename).strip() == b"big"

    def read(self, name: str) -> bytes:
        info = self.members.get(name)
        if info is None:
            raise ModelFileError(self.path, "the archive has no such member", key=name)
        if info.flag_bits & 0x1 or info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
            raise ModelFileError(self.path, "the member is encrypted or compressed in an unknown way", key=name)
        if info.compress_type == zipfile.ZIP_DEFLATED and info.file_size > max(
            1 << 20, MAX_DEFLATE_RATIO * info.compress_size
        ):
            raise ModelFileError(self.path, "the member declares more bytes than deflate can give", key=name)
        self.budget.charge(info.file_size, f"member {name}")
        with self.zip.open(info) as member:
            data = member.read(info.file_size + 1)
        if len(data) != info.file_size:
            raise ModelFileError(self.path, f"the member holds {len(data)} bytes, not {info.file_size}", key=name)
        return data


class _TorchUnpickler(_SafeUnpickler):
    """The allow-list unpickler plus torch's tensors, OrderedDict, and inert placeholders for the rest."""

    def __init__(self, file: _BoundedReader, budget: LoadBudget, archive: _Archive) -> None:
        super().__init__(file, budget)
        self.archive = archive
        self._storages: dict[str, Storage] = {}
        self._storage_types: dict[str, StorageType] = {}
        extra = {
            "_rebuild_tensor_v2": self._rebuild_tensor,
            "_rebuild_parameter": self._rebuild_parameter,
            "_rebuild_parameter_with_state": self._rebuild_parameter,
            "_rebuild_from_type_v2": self._rebuild_from_type,
            "OrderedDict": self._ordered_dict,
        }
        self._functions.update(extra)
        self._callable_ids |= {id(f) for f in extra.values()}

    def find_class(self, module: str, name: str) -> Any:
        if len(module) > MAX_GLOBAL_NAME or len(name) > MAX_GLOBAL_NAME:
            raise UnsafePickleError("the pickle names a global with an over-long name")
        if module == "torch._utils" and name in ("_rebuild_tensor_v2", "_rebuild_parameter",
                                                 "_rebuild_parameter_with_state"):  # fmt: skip
            return self._functions[name]
        if module == "torch._tensor" and name == "_rebuild_from_type_v2":
            return self._functions[name]
        if module == "torch" and name in STORAGE_DTYPES:
            return self._storage_types.setdefault(name, StorageType(name))
        if module == "collections" and name == "OrderedDict":
            return self._functions[name]
        try:
            return super().find_class(module, name)
        except UnsafePickleError:
            return self._stand_in(Opaque, module, name)

    # -- tensors -----------------------------------------------------------------------------------
    def persistent_load(self, pid: Any) -> Any:
        if not (type(pid) is tuple and len(pid) == 5 and pid[0] == "storage"):
            raise UnsafePickleError("a persistent id that is not a torch storage")
        kind, key, _location, numel = pid[1:]
        if not isinstance(kind, StorageType):
            raise UnsafePickleError(f"storage type {getattr(kind, 'name', type(kind).__name__)} is not supported")
        if not (type(key) is str and _KEY.match(key)) or type(numel) is not int or numel < 0:
            raise UnsafePickleError("a storage's key or size is malformed")
        if key in self._storages:
            storage = self._storages[key]
            if storage.values.dtype != kind.dtype and kind.name != "BFloat16Storage":
                raise UnsafePickleError(f"storage {key} is used with two element types")
            return storage
        raw = self.archive.read(f"{self.archive.prefix}data/{key}")
        if len(raw) != numel * kind.dtype.itemsize:
            raise ModelFileError(
                self.archive.path, f"the storage holds {len(raw)} bytes, not {numel} x {kind.dtype.itemsize}",
                key=f"data/{key}",
            )  # fmt: skip
        dtype = kind.dtype.newbyteorder(">") if self.archive.big_endian else kind.dtype
        values = np.frombuffer(raw, dtype=dtype, count=numel)
        if kind.name == "BFloat16Storage":
            self.budget.charge(4 * numel, "a bfloat16 storage widened to float32")
            values = (values.astype(np.uint32) << 16).view(np.float32)
        self._storages[key] = Storage(values.astype(values.dtype.newbyteorder("=")))
        return self._storages[key]

    def _rebuild_tensor(
        self, storage: Any, offset: Any, size: Any, stride: Any, requires_grad: Any = False, hooks: Any = None,
        metadata: Any = None,
    ) -> np.ndarray:  # fmt: skip
        """``torch._utils._rebuild_tensor_v2``: a copy of the strided view (size, stride, offset) of ``storage``."""
        if not isinstance(storage, Storage):
            raise UnsafePickleError("a tensor whose storage is not a torch storage")
        ints = (tuple, list)
        if not (isinstance(size, ints) and isinstance(stride, ints) and len(size) == len(stride) <= MAX_NDIM):
            raise UnsafePickleError("a tensor's size and stride are not matching tuples")
        if not all(type(v) is int for v in (offset, *size, *stride)) or offset < 0 or min((*stride, 0)) < 0:
            raise UnsafePickleError("a tensor's offset, size or stride is not a non-negative integer")
        shape = self.budget.check_shape(tuple(size), "a tensor")
        values = storage.values
        count = element_count(shape)
        if count:
            last = offset + sum((n - 1) * s for n, s in zip(shape, stride, strict=True))
            if last >= len(values):
                raise UnsafePickleError(f"a tensor reaches element {last} of a storage of {len(values)}")
        self.budget.charge(count * values.itemsize, "a tensor")
        if count == 0:
            return np.zeros(shape, values.dtype)
        view = np.lib.stride_tricks.as_strided(
            values[offset:], shape, tuple(s * values.itemsize for s in stride), writeable=False
        )
        return np.array(view)

    def _rebuild_parameter(self, data: Any, requires_grad: Any = False, hooks: Any = None, state: Any = None) -> Any:
        if not isinstance(data, np.ndarray):
            raise UnsafePickleError("a parameter whose data is not a tensor")
        return data

    def _rebuild_from_type(self, func: Any, new_type: Any, args: Any, state: Any = None) -> Any:
        """``torch._tensor._rebuild_from_type_v2``: the tensor ``func(*args)``; its subclass is dropped."""
        if id(func) not in self._callable_ids or not isinstance(args, tuple):
            raise UnsafePickleError("_rebuild_from_type_v2 of something that is not a tensor")
        return func(*args)

    def _ordered_dict(self, items: Any = ()) -> dict:
        if not isinstance(items, (list, tuple)) or not all(isinstance(i, (list, tuple)) and len(i) == 2 for i in items):
            raise UnsafePickleError("OrderedDict may only be built from (key, value) pairs")
        self.budget.charge(64 + 64 * len(items), "an OrderedDict")
        return dict(items)

    # -- placeholders --------------------------------------------------------------------------------
    def _call(self, func: Any, args: Any) -> Any:
        if isinstance(func, Opaque):  # calling a placeholder gives a placeholder (nothing is called)
            self.budget.charge(256, "a placeholder")
            return type(func)()
        return super()._call(func, args)

    def _instantiate(self, cls: Any) -> Any:
        if isinstance(cls, Opaque):
            self.budget.charge(256, "a placeholder")
            return type(cls)()
        return super()._instantiate(cls)

    def _target(self, kind: type) -> Any:
        if isinstance(self.stack[-1], Opaque):
            return kind()  # items of a placeholder (a dict or list subclass): dropped
        return super()._target(kind)

    def load_build(self) -> None:
        if type(self.stack[-2]) is dict and isinstance(self.stack[-1], dict):
            self.stack.pop()  # an OrderedDict's state (state_dict's _metadata): dropped
            return
        super().load_build()

    dispatch = _SafeUnpickler.dispatch.copy()
    dispatch[pickle.BUILD[0]] = load_build


def load_torch_file(path: str | Path) -> Any:
    """The contents of a ``torch.save`` file (zip format, torch ≥ 1.6) with tensors as NumPy arrays.

    Dicts, lists, tuples, numbers and strings come back as themselves, tensors and parameters as NumPy
    arrays (float32 stays float32; bfloat16 becomes float32), ``OrderedDict`` as ``dict``, and anything
    else as an inert :class:`Opaque` placeholder. Nothing in the file is run; torch is not imported.

    Raises
    ------
    ModelFileError
        naming the file (and the member): missing or not a regular file, not a zip checkpoint (e.g.
        torch's legacy pre-1.6 format), truncated or corrupt, a tensor outside its storage, or data past
        the file's budget.
    """
    path = Path(path)
    fh, size = open_regular(path)
    budget = LoadBudget(path, size)
    with fh:
        head = fh.read(4)
        fh.seek(0)
        if head != _ZIP_MAGIC:
            legacy = head[:1] == b"\x80"
            raise ModelFileError(
                path,
                "a torch file in the legacy (torch < 1.6) format, which cannot be read without torch; re-save it "
                "with torch >= 1.6 (torch.save(torch.load(path), path))"
                if legacy
                else f"not a PyTorch checkpoint (a zip archive written by torch.save); found {head!r}",
            )
        try:
            archive = _Archive(path, fh, budget)
            data = archive.read(archive.prefix + "data.pkl")
            unpickler = _TorchUnpickler(_BoundedReader(io.BytesIO(data), len(data)), budget, archive)
            return materialize(unpickler.load(), budget)
        except ModelFileError:
            raise
        except Exception as exc:  # noqa: BLE001 - refused globals, zip damage, EOF, bad values: a file error
            raise _corrupt(path, exc) from None
