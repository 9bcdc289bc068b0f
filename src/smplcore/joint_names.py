"""smplx's ``joint_names`` module: this name is :mod:`smplcore.smplx_compat.joint_names` itself."""

import sys

from smplcore.smplx_compat import joint_names as _module

sys.modules[__name__] = _module
