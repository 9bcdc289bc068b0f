"""Rebuilding pickled ``scipy.sparse`` matrices, with every index checked before SciPy sees it.

SciPy's ``toarray`` trusts ``indices`` / ``indptr``: out-of-range values write outside the dense
result. So the shape (which model files make dense later, so ``rows x cols`` is charged to the budget,
unless the budget says the matrix stays sparse), the lengths, the ordering of ``indptr`` and the range of
every index are checked first.
"""

from __future__ import annotations

import pickle
from typing import Any

import numpy as np

from smplcore.io.budgets import LoadBudget


def _vector(state: dict, key: str, kinds: str, what: str) -> np.ndarray:
    value = state.get(key)
    if not isinstance(value, np.ndarray) or value.ndim != 1 or value.dtype.kind not in kinds:
        found = f"{value.dtype} array of shape {value.shape}" if isinstance(value, np.ndarray) else type(value).__name__
        raise pickle.UnpicklingError(
            f"{what}: '{key}' must be a 1-d {'integer' if kinds == 'iu' else 'numeric'} array, found {found}"
        )
    return value


def _in_range(index: np.ndarray, size: int, what: str, key: str) -> None:
    if index.size and (int(index.min()) < 0 or int(index.max()) >= size):
        raise pickle.UnpicklingError(
            f"{what}: '{key}' must lie in [0, {size}), found [{int(index.min())}, {int(index.max())}]"
        )


def sparse_value(name: str, state: dict[str, Any], budget: LoadBudget) -> Any:
    """A ``scipy.sparse`` matrix of class ``name`` (``csc_matrix``, ``csr_matrix``, ``coo_matrix``, or
    the ``*_array`` forms) from its materialized pickled state."""
    import scipy.sparse as sp

    what = f"pickled {name}"
    shape = state.get("_shape", state.get("shape"))
    if not isinstance(shape, tuple) or len(shape) != 2:
        raise pickle.UnpicklingError(f"{what}: expected a (rows, cols) shape, found {type(shape).__name__}")
    if budget.sparse_stays_sparse:  # its entries were charged as arrays; only the row pointers are new
        rows, cols = (budget.check_shape((n,), what)[0] for n in shape)
        budget.charge(8 * (max(rows, cols) + 1), f"{what} of shape ({rows}, {cols})")
    else:
        rows, cols = budget.check_shape(shape, what)
        budget.charge(8 * rows * cols, f"{what} of shape ({rows}, {cols}) made dense")
    data = _vector(state, "data", "biuf", what)
    fmt = name[:3]
    if fmt == "coo":
        row, col = _vector(state, "row", "iu", what), _vector(state, "col", "iu", what)
        if not (len(row) == len(col) == len(data)):
            raise pickle.UnpicklingError(f"{what}: row, col and data differ in length")
        _in_range(row, rows, what, "row")
        _in_range(col, cols, what, "col")
        return sp.coo_matrix((data, (row.astype(np.int64), col.astype(np.int64))), shape=(rows, cols))
    indices, indptr = _vector(state, "indices", "iu", what), _vector(state, "indptr", "iu", what)
    major, minor = (cols, rows) if fmt == "csc" else (rows, cols)
    if len(indptr) != major + 1:
        raise pickle.UnpicklingError(f"{what}: indptr must have {major + 1} entries, found {len(indptr)}")
    ptr = indptr.astype(np.int64)
    if ptr[0] != 0 or np.any(np.diff(ptr) < 0) or ptr[-1] != len(indices) or len(indices) != len(data):
        raise pickle.UnpicklingError(f"{what}: indptr must rise from 0 to the number of entries ({len(data)})")
    _in_range(indices, minor, what, "indices")
    cls = sp.csc_matrix if fmt == "csc" else sp.csr_matrix
    return cls((data, indices.astype(np.int64), ptr), shape=(rows, cols))
