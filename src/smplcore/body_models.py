"""smplx's ``body_models`` module: this name is :mod:`smplcore.smplx_compat.body_models` itself."""

import sys

from smplcore.smplx_compat import body_models as _module

sys.modules[__name__] = _module
