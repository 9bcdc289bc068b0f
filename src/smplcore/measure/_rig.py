"""The one place :mod:`smplcore.measure` reads model facts: the public contract, ``model.rig``."""

from __future__ import annotations

from typing import Any

from smplcore.model import Rig


def _rig_of(model: Any) -> Rig:
    """The :class:`smplcore.model.Rig` of a front end (``BodyModel`` or a torch module), or the rig itself."""
    if isinstance(model, Rig):
        return model
    rig = getattr(model, "rig", None)
    if not isinstance(rig, Rig):
        raise TypeError(
            f"model: expected a smplcore body model (BodyModel, smplcore.create(...)) or a Rig, got {type(model)}"
        )
    return rig
