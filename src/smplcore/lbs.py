"""smplx's ``lbs`` module: this name is :mod:`smplcore.smplx_compat.lbs` itself."""

import sys

from smplcore.smplx_compat import lbs as _module

sys.modules[__name__] = _module
