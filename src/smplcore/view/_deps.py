"""Optional dependencies of :mod:`smplcore.view` (see :mod:`smplcore._deps`): the extra is ``view``."""

from __future__ import annotations

import importlib
from types import ModuleType

from smplcore._deps import MissingDependencyError, install_hint, missing

INSTALL_HINT = install_hint("view")

__all__ = ["INSTALL_HINT", "MissingDependencyError", "require"]


def require(module: str, purpose: str, extra: str = "view") -> ModuleType:
    """Import ``module`` or raise :class:`MissingDependencyError` naming the extra that brings it."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise missing(module, purpose, extra, str(exc)) from None
