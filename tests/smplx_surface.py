"""A module's public surface as smplx code sees it: class tree, constants, attributes, parameters,
buffers, ``state_dict`` and which output fields a forward fills (used to compare smplcore with smplx)."""

from __future__ import annotations

from typing import Any

import torch

_CONSTANTS = (
    "NUM_JOINTS",
    "NUM_BODY_JOINTS",
    "NUM_HAND_JOINTS",
    "NUM_FACE_JOINTS",
    "SHAPE_SPACE_DIM",
    "EXPRESSION_SPACE_DIM",
    "NECK_IDX",
)
_SCALARS = (
    "gender",
    "age",
    "batch_size",
    "dtype",
    "use_pca",
    "num_pca_comps",
    "flat_hand_mean",
    "is_rhand",
    "use_face_contour",
    "num_betas",
    "num_expression_coeffs",
)


def class_tree(cls: type) -> list[str]:
    """Names of the classes in the MRO up to (not including) nn.Module."""
    out = []
    for c in cls.__mro__:
        if c is torch.nn.Module:
            break
        out.append(c.__name__)
    return out


def surface(model: torch.nn.Module) -> dict[str, Any]:
    d: dict[str, Any] = {}
    d["constants"] = {k: getattr(model, k) for k in _CONSTANTS if hasattr(type(model), k)}
    d["scalars"] = {k: getattr(model, k) for k in _SCALARS if hasattr(model, k)}
    d["faces_dtype"] = str(model.faces.dtype)
    d["parameters"] = [(k, tuple(v.shape), str(v.dtype)) for k, v in model.named_parameters()]
    d["state_dict"] = {k: (tuple(v.shape), str(v.dtype)) for k, v in model.state_dict().items()}
    d["buffers"] = {k: (tuple(v.shape), str(v.dtype)) for k, v in model.named_buffers()}
    return d


def filled_fields(output: Any) -> dict[str, tuple | None]:
    """Each output field's shape, or None where the field is None."""
    return {k: (None if v is None else tuple(v.shape)) for k, v in output.items()}
