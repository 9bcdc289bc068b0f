"""The exporters' old name for :mod:`smplcore.uv` (UV maps and textures, shared by export, render and view): this
name is that module itself, so ``from smplcore.export.uv import model_uv`` keeps working."""

import sys

from smplcore import uv as _module

sys.modules[__name__] = _module
