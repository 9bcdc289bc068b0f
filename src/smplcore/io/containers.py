"""Reading the containers model files come in (pickle, .npz, .npy) into mappings of arrays, safely.

Only regular files are opened (a FIFO or device at the model path is refused from ``os.stat``,
and the file is opened non-blocking). Every read is bounded by the file's
:class:`~smplcore.io.budgets.LoadBudget`; ``.npz`` members are read lazily, only when a key is
used. Every failure is a :class:`~smplcore.errors.ModelFileError` naming the file (and the key).
"""

from __future__ import annotations

import io
import os
import stat
import zipfile
import zlib
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import IO, Any, BinaryIO, cast

import numpy as np

from smplcore.errors import ModelFileError
from smplcore.io.budgets import MAX_DEFLATE_RATIO, MAX_ZIP_MEMBERS, LoadBudget, element_count
from smplcore.io.safe_pickle import UnsafePickleError, safe_load

_ZIP_MAGIC = b"PK\x03\x04"
_NPY_MAGIC = b"\x93NUMPY"
_HEADER_DTYPE_KINDS = "biufcSU"
_CHUNK = 16 << 20
_CRC_PIECE = 256 << 10  # a stored member is read (and its CRC-32 computed) in pieces that stay in the cache


def open_regular(path: Path, expected: str = "a model file") -> tuple[BinaryIO, int]:
    """Open ``path`` for reading if it is a regular file; return the file and its size.

    ``expected`` names what the file should be in messages. Nothing is opened unless ``os.stat`` shows a
    regular file, and the open is non-blocking: a FIFO never makes it wait for a writer."""
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise ModelFileError(path, "no such file") from None
    except OSError as exc:
        raise ModelFileError(path, f"cannot read ({exc.strerror or exc})") from None
    if stat.S_ISDIR(info.st_mode):
        raise ModelFileError(path, f"is a directory, expected {expected}")
    if not stat.S_ISREG(info.st_mode):
        raise ModelFileError(path, f"is not a regular file ({_file_kind(info.st_mode)}), expected {expected}")
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise ModelFileError(path, f"cannot read ({exc.strerror or exc})") from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):  # replaced between stat and open
        os.close(fd)
        raise ModelFileError(path, f"is not a regular file ({_file_kind(info.st_mode)}), expected {expected}")
    return os.fdopen(fd, "rb"), info.st_size


def _file_kind(mode: int) -> str:
    for test, name in (
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return name
    return "not a plain file"


def _corrupt(path: Path, exc: BaseException, key: str | None = None) -> ModelFileError:
    if isinstance(exc, UnsafePickleError):
        return ModelFileError(path, f"refused to load: {exc}; nothing in the file was run", key=key)
    return ModelFileError(path, f"truncated or corrupt file ({type(exc).__name__}: {exc})", key=key)


def read_container(path: str | Path) -> Mapping[str, Any]:
    """Read a ``.pkl``, ``.npz`` or ``.npy`` (holding a pickled dict) file into a mapping.

    The kind of file is told from its first bytes, not its name. Nothing in the file is executed:
    pickles go through :func:`smplcore.io.safe_pickle.safe_load`. An ``.npz`` gives a
    :class:`LazyNpz` whose members are read when first used.

    Raises
    ------
    ModelFileError
        Missing or non-regular file, unknown format, truncated or corrupt data, a pickle that asks
        for anything but arrays and sparse matrices, or data past the file's budget.
    """
    path = Path(path)
    fh, size = open_regular(path)
    budget = LoadBudget(path, size)
    with fh:
        try:
            head = fh.read(8)
            fh.seek(0)
            if head.startswith(_ZIP_MAGIC):
                return LazyNpz(path, fh, size, budget)
            if head.startswith(_NPY_MAGIC):
                value = read_npy(fh, budget, size)
                if isinstance(value, np.ndarray) and value.dtype == object and value.shape == ():
                    value = value.item()
                if not isinstance(value, dict):
                    raise ModelFileError(path, "this .npy file holds an array, not a dict of model arrays")
                return value
            if head[:1] == b"\x80" or head[:1] in (b"(", b"}"):
                value = safe_load(fh, budget, limit=size)
                if not isinstance(value, dict):
                    raise ModelFileError(path, f"the pickle holds a {type(value).__name__}, not a dict")
                return value
        except ModelFileError:
            raise
        except Exception as exc:  # noqa: BLE001 - every damage (zlib, zip flags, EOF, Overflow, ...) is a file error
            raise _corrupt(path, exc) from None
    raise ModelFileError(
        path, f"not a model file: expected a pickle (.pkl) or NumPy (.npz) file, found data starting with {head[:8]!r}"
    )


def read_array_file(path: str | Path) -> np.ndarray:
    """One numeric array from a ``.npy`` file (e.g. a kid template), with the loader's checks:
    regular file, budget, plain dtype, no pickles.

    Raises
    ------
    ModelFileError
        naming the file, for any failure.
    """
    path = Path(path)
    fh, size = open_regular(path)
    with fh:
        try:
            if fh.read(6) != _NPY_MAGIC:
                raise ModelFileError(path, "not a .npy file")
            fh.seek(0)
            value = read_npy(fh, LoadBudget(path, size), size)
        except ModelFileError:
            raise
        except Exception as exc:  # noqa: BLE001 - every damage is a file error
            raise _corrupt(path, exc) from None
    if not isinstance(value, np.ndarray) or value.dtype.kind not in "biuf":
        found = f"dtype {value.dtype}" if isinstance(value, np.ndarray) else type(value).__name__
        raise ModelFileError(path, f"expected a numeric array, found {found}")
    return value


def read_npy(fh: IO[bytes], budget: LoadBudget, limit: int) -> np.ndarray | Any:
    """Read one .npy array of at most ``limit`` bytes; object arrays are unpickled through the
    allow-list. The declared shape is checked against the budget before anything is allocated."""
    start = fh.tell()
    version = np.lib.format.read_magic(fh)
    reader = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
    if version not in reader:
        raise ValueError(f"unsupported .npy version {version}")
    shape, fortran, dtype = reader[version](fh)
    limit -= fh.tell() - start
    if dtype.hasobject:
        if dtype != np.dtype(object):
            raise ValueError(f"structured dtype with Python objects ({dtype}) is not allowed")
        return safe_load(fh, budget, limit=limit)
    if (
        dtype.fields is not None
        or dtype.subdtype is not None
        or dtype.kind not in _HEADER_DTYPE_KINDS
        or not dtype.itemsize
    ):
        raise ValueError(f"dtype {dtype} is not a plain numeric, bool or string type")
    shape = budget.check_shape(shape, ".npy header")
    count = element_count(shape)
    nbytes = count * dtype.itemsize
    if nbytes > limit:
        raise EOFError(
            f"the header declares {nbytes:,} bytes of data ({shape}, {dtype}) but the data holds at most {limit:,}"
        )
    budget.charge(nbytes, f".npy data of shape {shape}")
    data = _read_exactly(fh, nbytes)
    array = np.frombuffer(data, dtype=dtype, count=count)
    return array.reshape(shape[::-1]).T if fortran else array.reshape(shape)


def _read_npy(fh: BinaryIO) -> np.ndarray | Any:
    """Read one .npy array from an in-memory stream (kept for callers holding the bytes already)."""
    start = fh.tell()
    size = fh.seek(0, io.SEEK_END) - start
    fh.seek(start)
    return read_npy(fh, LoadBudget("<.npy data>", size), size)


def _read_exactly(fh: IO[bytes], nbytes: int) -> np.ndarray:
    """``nbytes`` bytes of ``fh``, read in chunks straight into one buffer (no second full-size copy; the
    buffer is not zero-filled first: every byte is written by the read)."""
    out = np.empty(nbytes, dtype=np.uint8)
    view, got = out.data, 0
    while got < nbytes:
        count = fh.readinto(view[got : got + min(nbytes - got, _CHUNK)])  # type: ignore[attr-defined]
        if not count:
            raise EOFError(f"expected {nbytes} bytes of array data, found {got}")
        got += count
    return out


def _read_stored(fh: BinaryIO, start: int, info: zipfile.ZipInfo, budget: LoadBudget) -> np.ndarray | Any:
    """The .npy array of a stored (uncompressed) ``.npz`` member whose bytes begin at ``start`` in ``fh``
    (``zipfile`` has checked its local header): read from the file straight into the array's buffer, its CRC-32
    checked as ``zipfile`` checks it (computed piece by piece while each piece is in the cache; no chunk copies)."""
    fh.seek(start)
    member = _StoredMember(fh, info.file_size)
    value = read_npy(cast(IO[bytes], member), budget, info.file_size)
    while member.read(_CRC_PIECE):  # bytes after the array, if any
        pass
    if member.crc != info.CRC:
        raise zipfile.BadZipFile(f"Bad CRC-32 for file {info.filename!r}")
    return value


class _StoredMember:
    """The ``size`` bytes of a stored zip member from the current position of ``fh``, never more, with the
    CRC-32 of what was read so far."""

    def __init__(self, fh: BinaryIO, size: int) -> None:
        self.fh, self.left, self.crc, self._start = fh, size, 0, fh.tell()

    def tell(self) -> int:
        return self.fh.tell() - self._start

    def read(self, n: int | None = -1) -> bytes:
        n = self.left if n is None or n < 0 else min(n, self.left)
        data = self.fh.read(n)
        self.left -= len(data)
        self.crc = zlib.crc32(data, self.crc)
        return data

    def readline(self, limit: int = -1) -> bytes:
        line = self.fh.readline(self.left if limit < 0 else min(limit, self.left))
        self.left -= len(line)
        self.crc = zlib.crc32(line, self.crc)
        return line

    def readinto(self, buffer: Any) -> int:
        view = memoryview(buffer).cast("B")[: self.left]
        got = 0
        while got < len(view):
            count = self.fh.readinto(view[got : got + _CRC_PIECE])  # type: ignore[attr-defined]
            if not count:
                break
            self.crc = zlib.crc32(view[got : got + count], self.crc)
            got += count
        self.left -= got
        return got


class LazyNpz(Mapping):
    """The members of an ``.npz``, each read (through the file's budget) when first used.

    Opens the file again for each member read; keeps no file open.
    """

    def __init__(self, path: Path, fh: BinaryIO, size: int, budget: LoadBudget) -> None:
        self.path, self.budget = path, budget
        self._cache: dict[str, Any] = {}
        self._members = self._index(fh, size)

    def _index(self, fh: BinaryIO, size: int) -> dict[str, zipfile.ZipInfo]:
        # the end record, to count entries before parsing them all (private zipfile API, not in typeshed)
        end = zipfile._EndRecData(fh)  # type: ignore[attr-defined]
        if end is None:
            raise zipfile.BadZipFile("no end of central directory record")
        count = end[zipfile._ECD_ENTRIES_TOTAL]  # type: ignore[attr-defined]
        if count > MAX_ZIP_MEMBERS:
            raise ModelFileError(
                self.path, f"the archive lists {count} members; model files have at most {MAX_ZIP_MEMBERS}"
            )
        fh.seek(0)
        members: dict[str, zipfile.ZipInfo] = {}
        with zipfile.ZipFile(fh) as archive:
            for info in archive.infolist():
                key = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
                if key in members:
                    raise ModelFileError(self.path, "the archive holds two members of this name", key=key)
                members[key] = info
        return members

    def __iter__(self) -> Iterator[str]:
        return iter(self._members)

    def __len__(self) -> int:
        return len(self._members)

    def __contains__(self, key: object) -> bool:
        return key in self._members

    def __getitem__(self, key: str) -> Any:
        if key not in self._members:
            raise KeyError(key)
        if key not in self._cache:
            self._cache[key] = self._read(key)
        return self._cache[key]

    def _read(self, key: str) -> Any:
        info = self._members[key]
        self.budget.key = key
        try:
            if info.flag_bits & 0x1:
                raise ModelFileError(self.path, "the member is encrypted", key=key)
            if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
                raise ModelFileError(
                    self.path,
                    f"the member uses zip compression method {info.compress_type}; .npz files use stored or deflate",
                    key=key,
                )
            ratio_cap = max(1 << 20, MAX_DEFLATE_RATIO * info.compress_size)
            if info.compress_type == zipfile.ZIP_DEFLATED and info.file_size > ratio_cap:
                raise ModelFileError(
                    self.path,
                    f"the member declares {info.file_size:,} bytes from {info.compress_size:,} compressed "
                    f"(deflate cannot expand more than ~1032:1)",
                    key=key,
                )
            if info.compress_type == zipfile.ZIP_STORED and info.file_size != info.compress_size:
                raise ModelFileError(self.path, "a stored member's sizes disagree", key=key)
            fh, _ = open_regular(self.path)
            with fh, zipfile.ZipFile(fh) as archive, archive.open(info) as member:
                start = getattr(member, "_orig_compress_start", None)  # where the member's bytes begin
                if info.compress_type == zipfile.ZIP_STORED and isinstance(start, int):
                    return _read_stored(fh, start, info, self.budget)
                return read_npy(member, self.budget, info.file_size)
        except ModelFileError:
            raise
        except Exception as exc:  # noqa: BLE001 - zlib.error, BadZipFile (CRC), EOF, header errors, ...
            raise _corrupt(self.path, exc, key) from None
        finally:
            self.budget.key = None
