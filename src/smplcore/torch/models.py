"""PyTorch modules with smplx's public API (``create``, ``SMPL``, ``SMPLLayer``, ...) over smplcore's engine.

The classes form smplx's tree (``SMPLX ⊂ SMPLH ⊂ SMPL``, ``MANO ⊂ SMPL``, ``FLAME ⊂ SMPL``, each Layer a
subclass of its model) and carry smplx's constants, attributes, parameters (in smplx's order), buffers
and ``state_dict``. :class:`SMPL` holds the one implementation; the subclasses only state data: their
family spec, parameters, forward's positional order and output class. Where smplx misbehaves (the
README's "Differences from smplx") we do the right thing instead.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import torch

from smplcore.family.specs import FLAME as FLAME_SPEC
from smplcore.family.specs import MANO as MANO_SPEC
from smplcore.family.specs import OPEN as OPEN_SPEC
from smplcore.family.specs import SMPLH as SMPLH_SPEC
from smplcore.family.specs import SMPLX as SMPLX_SPEC
from smplcore.torch.outputs import FLAMEOutput, MANOOutput, ModelOutput, SMPLHOutput, SMPLOutput, SMPLXOutput
from smplcore.torch.selector import VertexJointSelector
from smplcore.torch.smpl import SMPL

__all__ = [
    "SMPL",
    "SMPLH",
    "SMPLX",
    "MANO",
    "FLAME",
    "OpenModel",
    "SMPLLayer",
    "SMPLHLayer",
    "SMPLXLayer",
    "MANOLayer",
    "FLAMELayer",
    "ModelOutput",
    "SMPLOutput",
    "SMPLHOutput",
    "SMPLXOutput",
    "MANOOutput",
    "FLAMEOutput",
    "VertexJointSelector",
]


_SMPLH_ARGS = ("betas", "global_orient", "body_pose", "left_hand_pose", "right_hand_pose", "transl")
_TAIL = ("return_verts", "return_full_pose", "pose2rot")


class SMPLH(SMPL):
    """SMPL+H: SMPL's body with articulated hands (52 joints; outputs 73)."""

    SPEC = SMPLH_SPEC
    FORWARD_ARGS: tuple[str, ...] = _SMPLH_ARGS + _TAIL
    OUTPUT = SMPLHOutput
    NUM_BODY_JOINTS = 21
    NUM_HAND_JOINTS = 15
    NUM_JOINTS = 51
    PARAMETERS = SMPL.PARAMETERS + ("left_hand_pose", "right_hand_pose")


class SMPLX(SMPLH):
    """SMPL-X: body, hands and face (55 joints; outputs 127, or 144 with the face contour)."""

    SPEC = SMPLX_SPEC
    DEFAULT_EXT = "npz"
    FORWARD_ARGS = _SMPLH_ARGS + ("expression", "jaw_pose", "leye_pose", "reye_pose") + _TAIL + ("return_shaped",)
    OUTPUT = SMPLXOutput
    MAPPER_TAKES_VERTICES = True
    NUM_BODY_JOINTS = 21
    NUM_HAND_JOINTS = 15
    NUM_FACE_JOINTS = 3
    NUM_JOINTS = 54
    EXPRESSION_SPACE_DIM = 100
    NECK_IDX = 12
    PARAMETERS = SMPLH.PARAMETERS + ("jaw_pose", "leye_pose", "reye_pose", "expression")


class MANO(SMPL):
    """MANO hand (16 joints). ``is_rhand`` picks ``MANO_RIGHT``/``MANO_LEFT`` in a folder.

    ``fix_left_shapedirs=True`` (left hand only) flips the sign of the x-component of the shape
    blend shapes, the known error of the official left-hand file.
    """

    SPEC = MANO_SPEC
    FORWARD_ARGS = ("betas", "global_orient", "hand_pose", "transl", "return_verts", "return_full_pose")
    OUTPUT = MANOOutput
    NUM_BODY_JOINTS = 1
    NUM_HAND_JOINTS = 15
    NUM_JOINTS = 16
    PARAMETERS = SMPL.PARAMETERS + ("hand_pose",)
    LAYER_PARAMETERS = ("body_pose",)

    def __init__(
        self,
        model_path: str | Path | None = None,
        *,
        is_rhand: bool = True,
        fix_left_shapedirs: bool = False,
        **kwargs: Any,
    ) -> None:
        super().__init__(model_path, is_rhand=is_rhand, **kwargs)
        self.is_rhand = self.setup.data.gender != "left"
        if fix_left_shapedirs and not self.is_rhand:
            self.fix_left_shapedirs()

    @torch.no_grad()
    def fix_left_shapedirs(self) -> None:
        """Flip the x-component of the left hand's shape blend shapes (the official file's sign error)."""
        if self.is_rhand:
            raise ValueError("fix_left_shapedirs: only the left MANO hand has the sign error")
        self.shapedirs[:, 0, :] *= -1
        flipped = self.setup.shapedirs.copy()
        flipped[:, 0, :] *= -1
        self.setup.shapedirs = flipped  # the setup (and so the rig and fitting) matches the buffer
        self.setup._cache.pop("rig", None)


class FLAME(SMPL):
    """FLAME head (5 joints; outputs 56, or 73 with the face contour)."""

    SPEC = FLAME_SPEC
    FORWARD_ARGS = (
        "betas",
        "global_orient",
        "neck_pose",
        "transl",
        "expression",
        "jaw_pose",
        "leye_pose",
        "reye_pose",
        "return_verts",
        "return_full_pose",
        "pose2rot",
    )
    OUTPUT = FLAMEOutput
    MAPPER_TAKES_VERTICES = True
    NUM_JOINTS = 5
    SHAPE_SPACE_DIM = 300
    EXPRESSION_SPACE_DIM = 100
    NECK_IDX = 0
    PARAMETERS = SMPL.PARAMETERS + ("neck_pose", "jaw_pose", "leye_pose", "reye_pose", "expression")
    LAYER_PARAMETERS = ("body_pose", "transl")


class OpenModel(SMPL):
    """smplcore's open CC0 body model in the SMPL layout (24 joints; outputs 45). Loads with no files."""

    SPEC = OPEN_SPEC

    def name(self) -> str:
        return "OPEN"


def _layer(cls: type, doc: str, **extra: Any) -> type:
    return type(f"{cls.__name__}Layer", (cls,), {"LAYER": True, "__doc__": doc, "__module__": __name__, **extra})


SMPLLayer = _layer(SMPL, "SMPL taking rotation matrices (B, J, 3, 3) and holding no parameters.")
SMPLHLayer = _layer(SMPLH, "SMPL+H taking rotation matrices (B, J, 3, 3) and holding no parameters.")
SMPLXLayer = _layer(
    SMPLX,
    "SMPL-X taking rotation matrices (B, J, 3, 3) and holding no parameters.",
    OUTPUT_TRANSL=True,
    FORWARD_ARGS=SMPLX.FORWARD_ARGS[:12],  # smplx's SMPLXLayer.forward has no pose2rot nor return_shaped
)
MANOLayer = _layer(MANO, "MANO taking rotation matrices (B, J, 3, 3); like smplx's, it holds only body_pose.")
FLAMELayer = _layer(
    FLAME, "FLAME taking rotation matrices (B, J, 3, 3); like smplx's, it holds only body_pose and transl."
)
