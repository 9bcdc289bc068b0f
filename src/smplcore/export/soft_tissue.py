"""DMPL soft tissue in exports: a model created with ``dmpl_path`` and an input with ``dmpls`` (T, n).

Meshes (``.obj`` / ``.ply``) bake the frame's soft tissue into the vertices; glTF carries it as morph
targets ``dmpl_0`` ... whose weights are the per-frame coefficients (the rig's skeleton is the one without
soft tissue); BVH holds no mesh, so nothing of it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from smplcore.errors import ShapeError
from smplcore.model.params import fit_width


def dmpls_of(model: Any, source: Any, frames: int) -> np.ndarray | None:
    """(T, n) the input's DMPL coefficients fitted to the model's count, or None (no DMPL file or no ``dmpls``)."""
    width = int(getattr(model, "num_dmpls", 0))
    value = getattr(source, "dmpls", None) if not isinstance(source, Mapping) else source.get("dmpls")
    if not width or value is None:
        return None
    value = np.asarray(value, np.float64)
    value = value.reshape(1, -1) if value.ndim < 2 else value
    if value.shape[0] not in (1, frames):
        raise ShapeError(f"dmpls: expected shape ({frames}, n) or (1, n), got {value.shape}")
    value = fit_width("dmpls", value, width)  # the one coefficient rule (smplcore.model.params)
    return np.broadcast_to(value, (frames, width)).copy()


def dmpl_joint_shift(model: Any, dmpls: np.ndarray) -> float:
    """Largest distance (metres) the (T, n) ``dmpls`` move a rest joint of ``model`` (through its regressor):
    what a rig, whose skeleton is the one without soft tissue, leaves out."""
    joint_dirs = model.rig.joint_dmpldirs  # (J, 3, n)
    moved = np.einsum("tk,jdk->tjd", dmpls, joint_dirs)
    return float(np.linalg.norm(moved, axis=-1).max()) if moved.size else 0.0
