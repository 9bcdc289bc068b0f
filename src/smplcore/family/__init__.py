"""The models of the SMPL family as data (see :mod:`smplcore.family.specs`)."""

from smplcore.family.specs import SPECS, FamilySpec, PoseBlock, get_spec

__all__ = ["SPECS", "FamilySpec", "PoseBlock", "get_spec"]
