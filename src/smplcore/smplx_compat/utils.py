"""smplx's ``utils`` module API: output classes, ``to_tensor``, ``to_np``, ``Struct``."""

from __future__ import annotations

from typing import Any

import numpy as np

from smplcore.smplx_compat.lbs import rot_mat_to_euler
from smplcore.torch.outputs import FLAMEOutput, MANOOutput, ModelOutput, SMPLHOutput, SMPLOutput, SMPLXOutput

__all__ = [
    "ModelOutput",
    "SMPLOutput",
    "SMPLHOutput",
    "SMPLXOutput",
    "MANOOutput",
    "FLAMEOutput",
    "Struct",
    "to_tensor",
    "to_np",
    "find_joint_kin_chain",
    "rot_mat_to_euler",
    "Tensor",
    "Array",
]

Tensor = Any
Array = np.ndarray


def find_joint_kin_chain(joint_id: int, kinematic_tree: Any) -> list[int]:
    """``joint_id``, its parent, ..., the root."""
    chain = []
    while joint_id != -1:
        chain.append(int(joint_id))
        joint_id = int(kinematic_tree[joint_id])
    return chain


def to_tensor(array: Any, dtype: Any = None) -> Any:
    import torch

    dtype = torch.float32 if dtype is None else dtype
    if torch.is_tensor(array):
        return array
    return torch.tensor(np.asarray(array), dtype=dtype)


class Struct:
    """Attribute access to keyword arguments (smplx's model-data holder)."""

    def __init__(self, **kwargs: Any) -> None:
        for key, val in kwargs.items():
            setattr(self, key, val)


def to_np(array: Any, dtype: Any = np.float32) -> np.ndarray:
    if hasattr(array, "toarray"):  # scipy.sparse
        array = array.toarray()
    return np.array(array, dtype=dtype)
