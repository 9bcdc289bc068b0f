"""Checks on the values read from a model file; each failure names the file, key, expected and found."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, Literal, TypeVar, overload

import numpy as np

from smplcore.errors import ModelFileError
from smplcore.io.budgets import MAX_LIST_NODES, nested_list_size

_FLOAT32_MAX = float(np.finfo(np.float32).max)
T = TypeVar("T")


class Checker:
    """Pulls keys out of a raw mapping with checks that name the file and key.

    :meth:`run` turns any other exception raised while converting the file into a
    :class:`ModelFileError` naming the file and the key being read when it happened.
    """

    def __init__(self, path: Path, raw: Mapping[str, Any]):
        self.path, self.raw = path, raw
        self.key: str | None = None

    def run(self, convert: Callable[..., T], *args: Any) -> T:
        try:
            odd = [k for k in self.raw if not isinstance(k, str)]
            if odd:
                raise self.error(f"expected text keys, found a {type(odd[0]).__name__} key ({len(odd)} in all)")
            return convert(self, *args)
        except ModelFileError:
            raise
        except Exception as exc:  # noqa: BLE001 - anything unusable in a file is a file error
            raise ModelFileError(self.path, f"unusable value ({type(exc).__name__}: {exc})", key=self.key) from None

    def error(self, message: str, key: str | None = None) -> ModelFileError:
        return ModelFileError(self.path, message, key=key or self.key)

    @overload
    def get(self, key: str, *, required: Literal[True] = True) -> np.ndarray: ...
    @overload
    def get(self, key: str, *, required: bool) -> np.ndarray | None: ...

    def get(self, key: str, *, required: bool = True) -> np.ndarray | None:
        """The value under ``key`` as a real numeric array (dense); None if absent and not required."""
        self.key = key
        if key not in self.raw:
            if required:
                raise self.error(f"missing key; the file has {sorted(self.raw)}", key)
            return None
        value = self.raw[key]
        if hasattr(value, "toarray"):  # scipy.sparse
            value = value.toarray()
        if type(value) in (list, tuple) and nested_list_size(value) > MAX_LIST_NODES:
            raise self.error(f"a nested list with more than {MAX_LIST_NODES:,} entries, expected an array", key)
        try:
            value = np.asarray(value)
        except Exception as exc:  # noqa: BLE001 - report anything unusable as a file error
            raise self.error(f"not an array ({type(exc).__name__}: {exc})", key) from None
        if value.dtype == object:
            raise self.error("holds Python objects, expected a numeric array", key)
        if value.dtype.kind == "c":
            raise self.error(f"expected real numbers, found complex values (dtype {value.dtype})", key)
        if value.dtype.kind not in "biuf":
            raise self.error(f"expected a numeric array, found dtype {value.dtype}", key)
        return value

    def expect(self, key: str, value: np.ndarray, shape: tuple, what: str = "") -> np.ndarray:
        """Check ``value.shape`` against ``shape`` (None entries match anything) and float values
        (finite, and within float32's range, which the models compute in by default)."""
        self.key = key
        ok = value.ndim == len(shape) and all(e is None or e == s for e, s in zip(shape, value.shape))
        if not ok:
            expected = "(" + ", ".join("*" if e is None else str(e) for e in shape) + ")"
            raise self.error(f"expected shape {expected}{what}, found {value.shape}", key)
        if value.dtype.kind == "f" and value.size:
            lo, hi = value.min(), value.max()  # NaN propagates; no temporary copies
            if not (np.isfinite(lo) and np.isfinite(hi)):
                raise self.error("contains NaN or infinite values", key)
            if value.dtype.itemsize > 4 and max(-float(lo), float(hi)) > _FLOAT32_MAX:
                raise self.error(
                    f"expected values within float32's range (|x| <= {_FLOAT32_MAX:.3g}), found values in "
                    f"[{float(lo):.3g}, {float(hi):.3g}]",
                    key,
                )
        return value

    def text(self, key: str) -> str:
        """A 0-d string array (or a str) under ``key`` as ``str``."""
        self.key = key
        value = self.raw[key]
        if isinstance(value, str):
            return value
        if not isinstance(value, np.ndarray) or value.shape != () or value.dtype.kind not in "US":
            found = (
                f"dtype {value.dtype}, shape {value.shape}" if isinstance(value, np.ndarray) else type(value).__name__
            )
            raise self.error(f"expected a string (0-d text array), found {found}", key)
        item = value.item()
        return item.decode("latin1") if isinstance(item, bytes) else str(item)

    def names(self, key: str, count: int | None = None) -> tuple[str, ...]:
        """A 1-d string array under ``key`` as a tuple of str, of ``count`` entries when given."""
        self.key = key
        value = self.raw[key]
        if not isinstance(value, np.ndarray) or value.ndim != 1 or value.dtype.kind not in "US":
            found = (
                f"dtype {value.dtype}, shape {value.shape}" if isinstance(value, np.ndarray) else type(value).__name__
            )
            raise self.error(f"expected a 1-d array of names, found {found}", key)
        if count is not None and value.shape[0] != count:
            raise self.error(f"expected {count} names, found {value.shape[0]}", key)
        return tuple(s.decode("latin1") if isinstance(s, bytes) else str(s) for s in value.tolist())


def check_index(path: Path, key: str, index: np.ndarray, size: int) -> np.ndarray:
    """``index`` as int64 after checking it is integer and lies in ``[0, size)``."""
    if index.dtype.kind not in "iu":
        raise ModelFileError(path, f"expected integer indices, found dtype {index.dtype}", key=key)
    if index.size and (index.min() < 0 or index.max() >= size):
        raise ModelFileError(path, f"indices must lie in [0, {size}), found [{index.min()}, {index.max()}]", key=key)
    return index.astype(np.int64)


def check_parents(path: Path, key: str, parents: np.ndarray, *, root_stored: bool = True) -> np.ndarray:
    """Parent index per joint as int64 (-1 for the root), after checking that every other joint's
    parent comes before it (``0 <= parent[j] < j``: no cycles, no joint its own parent).

    ``root_stored=False`` ignores the root's stored value (official files store 4294967295 or -1).
    """
    if parents.dtype.kind not in "iu":
        raise ModelFileError(path, f"expected integer joint indices, found dtype {parents.dtype}", key=key)
    if parents.shape[0] == 0:
        raise ModelFileError(path, "expected at least one joint, found none", key=key)
    out = parents.astype(np.int64)
    if not root_stored:
        out[0] = -1
    elif out[0] != -1:
        raise ModelFileError(path, f"expected -1 as the root's parent, found {out[0]}", key=key)
    joints = np.arange(out.shape[0])
    bad = np.flatnonzero((out[1:] < 0) | (out[1:] >= joints[1:])) + 1
    if bad.size:
        j = int(bad[0])
        what = "its own parent" if out[j] == j else ("a cycle or a later joint" if out[j] > j else "no valid parent")
        raise ModelFileError(
            path,
            f"expected every joint's parent to come before it (0 <= parent < joint); joint {j} has parent "
            f"{int(out[j])} ({what}; {bad.size} bad joint(s))",
            key=key,
        )
    return out
