"""smplx's ``utils`` module: this name is :mod:`smplcore.smplx_compat.utils` itself."""

import sys

from smplcore.smplx_compat import utils as _module

sys.modules[__name__] = _module
