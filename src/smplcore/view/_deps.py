"""Optional dependencies of :mod:`smplcore.view`, imported where used, with one clear error when missing."""

from __future__ import annotations

import importlib
from types import ModuleType

INSTALL_HINT = 'pip install "smplcore[view]"'


class MissingDependencyError(ImportError):
    """An optional dependency of the viewer or the video writer is not installed; the message says what to install."""


def require(module: str, purpose: str, extra: str = "view") -> ModuleType:
    """Import ``module`` or raise :class:`MissingDependencyError` naming the extra that brings it."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise MissingDependencyError(
            f'{purpose} needs {module.split(".")[0]} ({exc}); install it with: pip install "smplcore[{extra}]"'
        ) from None
