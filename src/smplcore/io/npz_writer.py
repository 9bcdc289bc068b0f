"""Writing a model as smplcore's own pickle-free ``.npz`` (read back by :func:`smplcore.io.load_model`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from smplcore.io.model_data import ModelData
from smplcore.io.model_files import FORMAT_TAG, load_model


def save_npz(data: ModelData, path: str | Path) -> Path:
    """Write ``data`` as smplcore's pickle-free ``.npz`` (loads with ``np.load(allow_pickle=False)``); the parent
    folders are created."""
    path = Path(path)
    arrays: dict[str, Any] = {"format": np.array(FORMAT_TAG)}
    for name in ("model_type", "gender"):
        arrays[name] = np.array(getattr(data, name))
    for name in (
        "v_template",
        "faces",
        "shapedirs",
        "posedirs",
        "J_regressor",
        "weights",
        "parents",
        "exprdirs",
        "hands_components_left",
        "hands_components_right",
        "hands_mean_left",
        "hands_mean_right",
        "lmk_faces_idx",
        "lmk_bary_coords",
        "dynamic_lmk_faces_idx",
        "dynamic_lmk_bary_coords",
        "vt",
        "ft",
    ):
        value = getattr(data, name)
        if value is not None:
            arrays[name] = np.asarray(value)
    if data.joint_names:
        arrays["joint_names"] = np.array(data.joint_names)
    if data.extra_joint_names:
        arrays["extra_joint_names"] = np.array(data.extra_joint_names)
        arrays["extra_joint_vertex_ids"] = np.asarray(data.extra_joint_vertex_ids, dtype=np.int64)
    if path.suffix != ".npz":
        raise ValueError(f"path: smplcore model files end in .npz, got {path.name!r}")
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **arrays)
    return path


def convert(src: str | Path, dst: str | Path, *, model_type: str | None = None, gender: str | None = None) -> Path:
    """Read any supported model file and write it as a clean smplcore ``.npz``."""
    return save_npz(load_model(src, model_type=model_type, gender=gender), dst)
