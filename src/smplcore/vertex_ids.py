"""smplx's ``vertex_ids`` module: this name is :mod:`smplcore.smplx_compat.vertex_ids` itself."""

import sys

from smplcore.smplx_compat import vertex_ids as _module

sys.modules[__name__] = _module
