"""What a torch class reads before it registers anything: the model's data (file, folder, smplx's
``data_struct``), whether the file has hand PCA, and a per-body ``v_template``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ShapeError
from smplcore.frontend.setup import template_array
from smplcore.io.model_data import ModelData

__all__ = ["has_hand_pca", "load_data", "per_body_templates"]


def load_data(
    cls: Any, model_path: Any, data_struct: Any, data: ModelData | None, gender: str, ext: str, is_rhand: bool
) -> ModelData:
    """The model's data: given, from smplx's ``data_struct``, or from the file or folder."""
    from smplcore.io.locate import read_model
    from smplcore.io.model_files import from_official_arrays

    spec = cls.SPEC
    if data is None and data_struct is not None:
        data = from_official_arrays(
            Path(f"<data_struct for {cls.__name__}>"), dict(vars(data_struct)), spec.model_type, gender
        )
    if data is None:
        data = read_model(model_path, spec.model_type, gender=gender, ext=ext, is_rhand=is_rhand)
    if data.model_type != spec.model_type:
        raise ValueError(
            f"{cls.__name__} cannot run a {data.model_type!r} model from {data.source}; "
            f"use smplcore.create() to pick the class from the file"
        )
    return data


def has_hand_pca(data: ModelData) -> bool:
    """Whether the file holds the PCA components of every hand of its model."""
    sides = {"left", "right"} if data.model_type != "mano" else {data.gender}
    return all(getattr(data, f"hands_components_{side}", None) is not None for side in sides)


def per_body_templates(options: dict[str, Any], data: ModelData) -> np.ndarray | None:
    """The ``v_template`` option when it holds one template per body, (B, V, 3) (smplx keeps it as that buffer
    and its forward uses it per body): checked and returned, and replaced in ``options`` by what the setup
    describes (the one template of a (1, V, 3), else the file's). None for a (V, 3) template or none."""
    value = options.get("v_template")
    if value is None or np.ndim(value) != 3:
        return None
    array = template_array(value)
    num_verts = data.v_template.shape[0]
    if array.shape[1:] != data.v_template.shape or array.shape[0] == 0:
        raise ShapeError(
            f"v_template: expected shape ({num_verts}, 3) or (B, {num_verts}, 3) (one template per body, B >= 1), "
            f"got {array.shape}"
        )
    options["v_template"] = array[0] if array.shape[0] == 1 else None
    return array
