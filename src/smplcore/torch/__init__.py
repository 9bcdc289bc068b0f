"""The PyTorch front end: smplx-compatible modules over smplcore's engine."""

from smplcore.torch.models import *  # noqa: F401,F403
from smplcore.torch.models import __all__  # noqa: F401
