"""Auxiliary files (priors, regressors, correspondences, keypoints, UVs, render inputs) read like model files.

Every file smplcore reads besides a model file goes through this module, so each gets what model files get:

* only a regular file is opened: a FIFO, device, socket or directory where a file is expected is refused
  from ``os.stat`` before anything is opened, and the file is opened non-blocking (no ``open()`` that waits
  for a writer); a symlink loop is a clear error;
* array containers (pickle, ``.npz``, ``.npy``) are read by the allow-list reader
  (:func:`smplcore.io.containers.read_container`) under the file's
  :class:`~smplcore.io.budgets.LoadBudget` (memory at most ``64 MiB + 8 x`` the file size);
* Python lists found in a pickle are walked before anything is made of them: a list whose sub-lists are
  shared through the pickle's memo (a few hundred bytes can describe 2**60 entries) is refused, as
  :class:`~smplcore.io.checks.Checker` refuses it in model files;
* text files (JSON, Wavefront OBJ) are read whole only up to ``MAX_TEXT_BYTES``; JSON nested past what
  Python's parser can take is a clear error, not a ``RecursionError``.

Every failure is a :class:`~smplcore.errors.ModelFileError` naming the file (and the key).
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ModelFileError
from smplcore.io.budgets import MIB, LoadBudget, nested_list_size
from smplcore.io.containers import (
    _NPY_MAGIC,
    _ZIP_MAGIC,
    LazyNpz,
    _corrupt,
    open_regular,
    read_npy,
)
from smplcore.io.safe_pickle import safe_load

__all__ = [
    "MAX_TEXT_BYTES",
    "numeric_array",
    "open_input",
    "read_arrays",
    "read_checkpoint",
    "read_json",
    "read_npz",
    "read_text",
]

MAX_LIST_NODES = 100_000
"""Entries (shared sub-lists counted each time) of all the Python lists an auxiliary file may hold: their data
is arrays; lists carry names and small tables. Walking this many takes milliseconds."""

MAX_TEXT_BYTES = 256 * MIB
"""Largest JSON / OBJ file read (COCO's 2017 keypoint annotations, the largest real input, are 238 MB).
Decoded JSON takes at most ~20x its text in Python objects (``[[],[],...]``), measured in the tests."""


def open_input(path: str | os.PathLike[str], expected: str) -> tuple[Any, int]:
    """Open ``path`` for binary reading if it is a regular file; return the file and its size.

    Parameters
    ----------
    path : the file.
    expected : what the file should be, for messages (``"a GMM prior (.pkl)"``).

    Raises
    ------
    ModelFileError
        Missing, unreadable, a directory, a FIFO / device / socket, or a symlink loop.
    """
    return open_regular(Path(path), expected)


def read_arrays(path: str | os.PathLike[str], expected: str, *, sparse_stays_sparse: bool = False) -> Any:
    """What a pickle, ``.npz`` or ``.npy`` file holds, read through the allow-list under the file's budget.

    Parameters
    ----------
    path : the file; its kind is told from its first bytes, not its name.
    expected : what the file should be, for messages.
    sparse_stays_sparse : charge pickled ``scipy.sparse`` matrices by their entries, not their dense size
        (a deformation-transfer map, 10475 x 13780, stays sparse).

    Returns
    -------
    A :class:`~smplcore.io.containers.LazyNpz` mapping for an ``.npz``; an array for a numeric ``.npy``;
    the unpickled value (dict, array, sparse matrix, list, ...) for a pickle or an object ``.npy``.
    Lists in it have at most ``MAX_LIST_NODES`` entries (shared sub-lists counted each time).

    Raises
    ------
    ModelFileError
        naming the file, for any failure (not a regular file, unknown format, truncated, unsafe, past
        the budget, over-shared lists).
    """
    path = Path(path)
    fh, size = open_regular(path, expected)
    budget = LoadBudget(path, size, sparse_stays_sparse=sparse_stays_sparse)
    with fh:
        try:
            head = fh.read(8)
            fh.seek(0)
            if head.startswith(_ZIP_MAGIC):
                return CheckedNpz(LazyNpz(path, fh, size, budget))
            if head.startswith(_NPY_MAGIC):
                value = read_npy(fh, budget, size)
                if isinstance(value, np.ndarray) and value.dtype == object and value.shape == ():
                    value = value.item()
            elif head[:1] == b"\x80" or head[:1] in (b"(", b"}", b"]"):
                value = safe_load(fh, budget, limit=size)
            else:
                raise ModelFileError(path, f"not {expected}: expected pickle or NumPy data, found {head!r}")
        except ModelFileError:
            raise
        except Exception as exc:  # noqa: BLE001 - every damage (EOF, zlib, zip flags, Overflow, ...) is a file error
            raise _corrupt(path, exc) from None
    _check_lists(path, value)
    return value


def read_checkpoint(path: str | os.PathLike[str], expected: str) -> Any:
    """The contents of a ``torch.save`` file (see :func:`smplcore.io.load_torch_file`), with the list check
    of :func:`read_arrays`; torch is not needed and nothing in the file is run."""
    from smplcore.io.torch_file import load_torch_file

    path = Path(path)
    open_regular(path, expected)[0].close()  # the message names what was expected
    value = load_torch_file(path)
    _check_lists(path, value)
    return value


class CheckedNpz(Mapping):
    """An ``.npz``'s members (read lazily through the file's budget), each with the list check of
    :func:`read_arrays` when first read (a member may be an object array holding a pickle)."""

    def __init__(self, npz: LazyNpz) -> None:
        self.npz, self.path = npz, npz.path
        self._checked: set[str] = set()

    def __iter__(self) -> Iterator[str]:
        return iter(self.npz)

    def __len__(self) -> int:
        return len(self.npz)

    def __contains__(self, key: object) -> bool:
        return key in self.npz

    def __getitem__(self, key: str) -> Any:
        value = self.npz[key]
        if key not in self._checked:
            _check_lists(self.path, value, key)
            self._checked.add(key)
        return value


def _check_lists(path: Path, value: Any, key: str | None = None) -> None:
    """Refuse a value whose lists, tuples and dicts hold more than MAX_LIST_NODES entries in all, counting
    a shared sub-list each time it is reached: what ``np.asarray`` or any walk of the value would visit."""
    count, todo = 0, [value]
    while todo:
        item = todo.pop()
        count += 1
        if count > MAX_LIST_NODES:
            raise ModelFileError(
                path,
                f"holds nested lists of more than {MAX_LIST_NODES:,} entries in all (sub-lists shared through "
                "the pickle's memo count each time they are used); expected arrays - the file is damaged or forged",
                key=key,
            )
        kind = type(item)
        if kind in (list, tuple):
            todo.extend(item)
        elif kind is dict:
            todo.extend(item.values())


def numeric_array(path: str | os.PathLike[str], value: Any, key: str | None = None, kinds: str = "biuf") -> np.ndarray:
    """``value`` (from a file) as a numeric array, or a ModelFileError naming the file and key.

    Sparse matrices are made dense; nested lists are counted first (see :func:`read_arrays`); object,
    complex, string and structured values are refused.
    """
    if hasattr(value, "toarray"):
        value = value.toarray()
    if type(value) in (list, tuple) and nested_list_size(value) > MAX_LIST_NODES:
        raise ModelFileError(path, f"a nested list of more than {MAX_LIST_NODES:,} entries, expected an array", key=key)
    try:
        array = np.asarray(value)
    except Exception as exc:  # noqa: BLE001 - ragged lists, odd objects: a file error
        raise ModelFileError(path, f"not an array ({type(exc).__name__}: {exc})", key=key) from None
    if array.dtype.kind not in kinds:
        raise ModelFileError(path, f"expected a numeric array, found dtype {array.dtype}", key=key)
    return array


def read_text(path: str | os.PathLike[str], expected: str, max_bytes: int = MAX_TEXT_BYTES) -> str:
    """The UTF-8 text of a regular file of at most ``max_bytes`` (undecodable bytes replaced)."""
    path = Path(path)
    fh, size = open_regular(path, expected)
    with fh:
        if size > max_bytes:
            raise ModelFileError(path, f"is {size:,} bytes; {expected} is read only up to {max_bytes:,} bytes")
        try:
            data = fh.read(size + 1)  # (not max_bytes: a read of n bytes allocates n first)
        except OSError as exc:
            raise ModelFileError(path, f"cannot read ({exc.strerror or exc})") from None
    if len(data) > max_bytes:  # grew after the stat
        raise ModelFileError(path, f"is more than {max_bytes:,} bytes; {expected} is read only up to that")
    return data.decode("utf-8", errors="replace")


def read_json(path: str | os.PathLike[str], expected: str, max_bytes: int = MAX_TEXT_BYTES) -> Any:
    """The parsed JSON of a regular file of at most ``max_bytes``.

    Raises
    ------
    ModelFileError
        naming the file: not a regular file, too large, not UTF-8, invalid JSON, nested too deep.
    """
    path = Path(path)
    fh, size = open_regular(path, expected)
    with fh:
        if size > max_bytes:
            raise ModelFileError(path, f"is {size:,} bytes; {expected} is read only up to {max_bytes:,} bytes")
        try:
            data = fh.read(size + 1)  # (not max_bytes: a read of n bytes allocates n first)
        except OSError as exc:
            raise ModelFileError(path, f"cannot read ({exc.strerror or exc})") from None
    if len(data) > max_bytes:
        raise ModelFileError(path, f"is more than {max_bytes:,} bytes; {expected} is read only up to that")
    try:
        return json.loads(data.decode("utf-8"))
    except RecursionError:
        raise ModelFileError(path, "not usable JSON: nested too deep for the parser") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ModelFileError(path, f"not valid JSON ({exc})") from None
    except (ValueError, MemoryError) as exc:  # e.g. an integer of more digits than Python converts
        raise ModelFileError(path, f"not usable JSON ({type(exc).__name__}: {exc})") from None


def read_npz(path: str | os.PathLike[str], expected: str) -> Mapping[str, Any]:
    """The members of an ``.npz`` (read lazily through the file's budget); ModelFileError for anything else."""
    value = read_arrays(path, expected)
    if not isinstance(value, CheckedNpz):
        raise ModelFileError(path, f"not {expected}: expected a NumPy .npz archive")
    return value
