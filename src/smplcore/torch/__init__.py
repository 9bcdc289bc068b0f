"""The PyTorch front end: smplx-compatible modules over smplcore's engine."""

from smplcore.torch.factory import build_layer, create
from smplcore.torch.models import *  # noqa: F401,F403
from smplcore.torch.models import __all__ as _models_all

BodyModule = SMPL  # noqa: F405  (the class every model derives from, by its former name)

__all__ = ["create", "build_layer", "BodyModule", *_models_all]
