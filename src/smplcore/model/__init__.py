"""The public model contract: :class:`Rig`, the facts of a model with its options applied, which every
front end exposes as ``model.rig`` and every consumer (fit, motion, export, view, measure) reads."""

from smplcore.model.rig import PoseBlock, Rig, UVMap, rig_from_setup

__all__ = ["PoseBlock", "Rig", "UVMap", "rig_from_setup"]
