"""Checks of mesh arguments (vertices, faces) shared by the consumers (render, export).

Every check accepts NumPy arrays, anything ``np.asarray`` takes, and torch tensors (without importing
torch), and raises errors that name the argument with the expected and the received shape.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from smplcore.errors import ShapeError


def as_array(name: str, value: Any) -> np.ndarray:
    """``value`` as a NumPy array (scipy.sparse densified, torch tensors detached)."""
    if value is None:
        raise ValueError(f"{name}: expected an array, got None")
    if hasattr(value, "toarray") and not isinstance(value, np.ndarray):  # scipy.sparse
        value = value.toarray()
    if hasattr(value, "detach") and hasattr(value, "cpu"):  # a torch tensor, without importing torch
        value = value.detach().cpu().numpy()
    try:
        return np.asarray(value)
    except Exception as exc:
        raise ValueError(f"{name}: could not be converted to a NumPy array ({exc})") from exc


def check_points(name: str, value: Any, expected: str, ndims: tuple[int, ...] = (2, 3)) -> np.ndarray:
    """A finite float64 (…, 3) array with one of ``ndims`` dimensions and at least one point."""
    arr = as_array(name, value)
    if arr.ndim not in ndims or arr.shape[-1] != 3 or arr.shape[-2] < 1 or (arr.ndim == 3 and arr.shape[0] < 1):
        raise ShapeError(f"{name}: expected shape {expected}, got {tuple(arr.shape)}")
    if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise ValueError(f"{name}: expected a float array, got dtype {arr.dtype}")
    arr = arr.astype(np.float64, copy=False)
    if not np.all(np.isfinite(arr)):
        bad = int(np.count_nonzero(~np.isfinite(arr)))
        raise ValueError(f"{name}: expected finite values, got {bad} NaN/inf value(s)")
    return arr


def check_faces(faces: Any, num_vertices: int) -> np.ndarray:
    """(F, 3) int64 triangle indices within ``[0, num_vertices)``."""
    arr = as_array("faces", faces)
    if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] < 1:
        raise ShapeError(f"faces: expected shape (F, 3) with F >= 1, got {tuple(arr.shape)}")
    if not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"faces: expected an integer array, got dtype {arr.dtype}")
    lo, hi = int(arr.min()), int(arr.max())
    if lo < 0 or hi >= num_vertices:
        raise ValueError(
            f"faces: indices must be in [0, {num_vertices - 1}] for {num_vertices} vertices, got values in [{lo}, {hi}]"
        )
    return arr.astype(np.int64, copy=False)
