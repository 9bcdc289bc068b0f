"""The public model contract: :class:`Rig`, the facts of a model with its options applied, which every
front end exposes as ``model.rig`` and every consumer (fit, motion, export, view, measure) reads."""

from typing import Any

from smplcore.model.evaluate import Evaluation, evaluate, model_arrays
from smplcore.model.rig import PoseBlock, Rig, UVMap, rig_from_setup

__all__ = [
    "SKINNING_METHODS",
    "Evaluation",
    "PoseBlock",
    "Rig",
    "UVMap",
    "check_skinning",
    "evaluate",
    "model_arrays",
    "rig_from_setup",
]

#: The skinning methods of the ``skinning`` option: linear blend and dual-quaternion skinning.
SKINNING_METHODS = ("lbs", "dqs")


def check_skinning(skinning: Any) -> str:
    """``skinning`` if it names a skinning method, else a ValueError naming the option and the choices."""
    from smplcore.frontend.setup import check_skinning as check

    return check(skinning)
