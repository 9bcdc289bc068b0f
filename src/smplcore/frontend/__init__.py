"""What both front ends (the torch modules and the NumPy ``BodyModel``) share: options resolved once
(:class:`ModelSetup`), inputs checked (:mod:`~smplcore.frontend.inputs`) and one evaluation returning a
typed :class:`Evaluation` (:func:`evaluate`)."""

from smplcore.frontend.evaluate import ArraySource, Evaluation, PlainArrays, evaluate
from smplcore.frontend.setup import SETUP_OPTIONS, Keypoints, ModelSetup, warn_once
from smplcore.frontend.sources import SetupArrays

__all__ = [
    "SETUP_OPTIONS",
    "ArraySource",
    "Evaluation",
    "Keypoints",
    "ModelSetup",
    "PlainArrays",
    "SetupArrays",
    "evaluate",
    "warn_once",
]
