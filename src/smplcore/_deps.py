"""Optional dependencies: imported where used, with one clear error naming the extra that brings them."""

from __future__ import annotations

import importlib
from types import ModuleType

from smplcore.errors import SmplcoreError

#: the extra of ``pip install "smplcore[...]"`` that brings each optional module (see pyproject.toml)
EXTRAS = {
    "torch": "torch",
    "trimesh": "export",
    "pygltflib": "export",
    "pxr": "export",
    "pyrender": "render",
    "OpenGL": "render",
    "PIL": "render",
    "tqdm": "cli",
    "ray": "ray",
    "viser": "view",
    "imageio_ffmpeg": "view",
    "threadpoolctl": "fit",
}

_DISPLAY = {"PIL": "Pillow", "OpenGL": "PyOpenGL", "pxr": "usd-core", "ray": "Ray"}

#: the tested torch release (the README's install line)
TORCH_INSTALL = "pip install torch==2.13.0"


def install_hint(extra: str) -> str:
    """``pip install "smplcore[extra]"``."""
    return f'pip install "smplcore[{extra}]"'


class MissingDependencyError(SmplcoreError, ImportError, RuntimeError):
    """An optional dependency is not installed; the message says what to install.

    Attributes: ``module`` (the missing top-level module), ``purpose`` (what needed it), ``extra`` (the
    smplcore extra that brings it). A ``RuntimeError`` too, as these errors used to be.
    """

    def __init__(self, message: str, *, module: str | None = None, purpose: str = "", extra: str | None = None):
        super().__init__(message, name=module)
        self.module, self.purpose, self.extra = module, purpose, extra


def missing(module: str, purpose: str, extra: str | None = None, reason: str | None = None) -> MissingDependencyError:
    """The error for ``module`` not installed (or not importable: ``reason``), needed for ``purpose``."""
    top = module.split(".")[0]
    extra = extra or EXTRAS.get(top)
    how = install_hint(extra) if extra else f"pip install {top}"
    what = f" ({reason})" if reason else ", which is not installed"
    return MissingDependencyError(
        f"{purpose} needs {_DISPLAY.get(top, top)}{what}; install it with: {how}",
        module=top,
        purpose=purpose,
        extra=extra,
    )


def require(module: str, purpose: str, extra: str | None = None) -> ModuleType:
    """Import ``module`` or raise :class:`MissingDependencyError` naming the extra that brings it."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise missing(module, purpose, extra, str(exc)) from None
