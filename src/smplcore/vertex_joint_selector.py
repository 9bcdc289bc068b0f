"""smplx's ``vertex_joint_selector`` module: this name is :mod:`smplcore.smplx_compat.vertex_joint_selector` itself."""

import sys

from smplcore.smplx_compat import vertex_joint_selector as _module

sys.modules[__name__] = _module
