"""How much work and memory reading one model file may cost, and why.

A model file comes from outside; whatever it declares (lengths, shapes, member sizes, how often a
value is reused), reading it must cost time and memory proportional to its size, and never more
than a real body model can need. Every reader in :mod:`smplcore.io` charges what it is about to
allocate to one :class:`LoadBudget` per file *before* allocating, and a file past its budget gets a
:class:`~smplcore.errors.ModelFileError` naming the file and key.

The numbers
-----------
``FLOOR_BYTES = 64 MiB`` and ``BYTES_PER_FILE_BYTE = 8``
    A file may make the loader allocate at most ``64 MiB + 8 x its size`` in arrays, strings and
    copied containers (capped at ``CEILING_BYTES``). Uncompressed containers (pickles, ``numpy.savez``
    archives) decode to about 1x their size (2x for Python 2 pickles, whose byte strings are
    decoded to text and encoded back); ``savez_compressed`` archives of real model data measured
    1.1x (random-like blend shapes) to 2.1x overall (the open model: 5.7 MB of arrays in 2.7 MB),
    so 8x leaves 4x headroom. The floor covers small files (MANO, landmark embeddings, the open
    model) whatever their compression, and is small next to any machine's memory.
``CEILING_BYTES = 4 GiB``
    The largest official files (SMPL-X ``.npz``, 100-300 MB) decode to well under 1 GB.
``MAX_ARRAY_ELEMENTS = 2**27`` (134 M)
    The largest array of any official model is SMPL-X's ``posedirs``, 10475 x 3 x 486 = 15.3 M
    values; 2**27 is ~9x that. A ``.npy`` header, a pickled array or a sparse matrix (which is
    made dense) declaring more is refused before anything is allocated.
``MAX_NDIM = 8``
    Model arrays have at most 3 dimensions.
``MAX_NESTING = 64``
    Tuples and containers in real files are nested a few levels deep. Deeper nesting is refused
    while unpickling: hashing a tuple nested a million deep overflows the C stack.
``MAX_ZIP_MEMBERS = 256``
    Official ``.npz`` files hold 15-30 arrays.
``MAX_DEFLATE_RATIO = 1100``
    Deflate cannot expand data more than ~1032:1, so a member declaring more is a forged header.
    (Mostly-zero arrays such as a dense joint regressor legitimately reach ~120:1.) Members are read
    lazily, only when used, streamed, and stop at their declared size; their declared size is
    charged to the budget first.
``MAX_LIST_NODES = 10**6``
    Python lists turned into arrays (never the form of large official arrays) may have at most
    this many nodes, counting shared sub-lists each time.
``MAX_GLOBAL_NAME = 200``
    Characters in a pickled module or class name (real ones are < 40).

Codecs: only ``latin1`` (Python 2 byte strings, Python 3 bytes at protocol 2), ``ascii`` and
``utf-8``; others (``punycode`` costs quadratic time) are refused.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from smplcore.errors import ModelFileError

MIB = 1 << 20
FLOOR_BYTES = 64 * MIB
BYTES_PER_FILE_BYTE = 8
CEILING_BYTES = 4096 * MIB
MAX_ARRAY_ELEMENTS = 2**27
MAX_NDIM = 8
MAX_NESTING = 64
MAX_ZIP_MEMBERS = 256
MAX_DEFLATE_RATIO = 1100
MAX_GLOBAL_NAME = 200
ALLOWED_CODECS = frozenset({"latin1", "latin-1", "latin_1", "iso-8859-1", "iso8859-1", "l1", "ascii", "utf-8", "utf8"})


class LoadBudget:
    """Bytes one file may make the loader allocate; :meth:`charge` before allocating.

    Parameters
    ----------
    path : the file (for messages).
    file_size : its size in bytes.
    sparse_stays_sparse : the file's sparse matrices are used as they are (not made dense).
    """

    def __init__(self, path: str | Path, file_size: int, *, sparse_stays_sparse: bool = False) -> None:
        self.path = str(path)
        self.file_size = int(file_size)
        # model files' sparse matrices (regressors) are made dense, so their dense size is charged; a
        # deformation-transfer map (10475 x 13780) stays sparse and costs only its entries
        self.sparse_stays_sparse = sparse_stays_sparse
        self.limit = min(CEILING_BYTES, FLOOR_BYTES + BYTES_PER_FILE_BYTE * self.file_size)
        self.used = 0
        self.key: str | None = None

    def refuse(self, message: str) -> ModelFileError:
        return ModelFileError(self.path, message, key=self.key)

    def charge(self, nbytes: int, what: str) -> None:
        """Count ``nbytes`` about to be allocated for ``what``; refuse past the budget."""
        nbytes = int(nbytes)
        if nbytes < 0:
            raise self.refuse(f"{what} declares a negative size ({nbytes})")
        if self.used + nbytes > self.limit:
            raise self.refuse(
                f"{what} would need {nbytes:,} bytes; this {self.file_size:,}-byte file may make the "
                f"loader allocate at most {self.limit:,} bytes in all ({self.used:,} used so far) - "
                "the file is damaged or forged"
            )
        self.used += nbytes

    def check_shape(self, shape: object, what: str) -> tuple[int, ...]:
        """``shape`` as a tuple of ints after checking rank and element count; refuse otherwise."""
        integer = (int, np.integer)
        if not isinstance(shape, (tuple, list)) or not all(
            isinstance(n, integer) and type(n) is not bool for n in shape
        ):
            raise self.refuse(f"{what}: expected a shape of integers, found {_short(shape)}")
        shape = tuple(int(n) for n in shape)
        if len(shape) > MAX_NDIM:
            raise self.refuse(f"{what}: expected at most {MAX_NDIM} dimensions, found {len(shape)}")
        if any(n < 0 for n in shape):
            raise self.refuse(f"{what}: negative dimension in shape {tuple(shape)}")
        count = 1
        for n in shape:
            count *= n
        if count > MAX_ARRAY_ELEMENTS:
            raise self.refuse(
                f"{what}: shape {tuple(shape)} declares {count:,} elements; no body model array has more "
                f"than {MAX_ARRAY_ELEMENTS:,}"
            )
        return tuple(shape)


def _short(value: object, limit: int = 80) -> str:
    text = repr(value) if isinstance(value, (int, float, str, bytes, type(None))) else type(value).__name__
    return text if len(text) <= limit else text[:limit] + "..."


def element_count(shape: tuple[int, ...]) -> int:
    count = 1
    for n in shape:
        count *= n
    return count


MAX_LIST_NODES = 10**6


def nested_list_size(value: object, limit: int = MAX_LIST_NODES) -> int:
    """Nodes of a nested list/tuple (shared sub-lists counted each time they are reached), or
    ``limit + 1`` as soon as there are more: a guard before ``np.asarray`` on a Python list, whose
    sub-lists a pickle can share to make it exponentially large."""
    count, todo = 0, [value]
    while todo:
        item = todo.pop()
        count += 1
        if count > limit:
            return count
        if isinstance(item, (list, tuple)) and type(item) in (list, tuple):  # subclasses are not walked
            todo.extend(item)
    return count
