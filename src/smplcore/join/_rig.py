"""Model facts for :mod:`smplcore.join`: the public model contract, read in one place."""

from __future__ import annotations

from typing import Any

from smplcore.model import Rig

RigFacts = Rig  # what joining reads: the contract's Rig


def _rig_of(model: Any) -> Rig:
    """The :class:`smplcore.model.Rig` of ``model`` (a :class:`smplcore.BodyModel` or ``smplcore.create(...)``)."""
    rig = getattr(model, "rig", None)
    if not isinstance(rig, Rig):
        raise TypeError(
            f"model: expected a smplcore model (BodyModel or smplcore.create(...)), got {type(model).__name__}"
        )
    return rig
