"""Exception types raised by smplcore."""

from __future__ import annotations

import os
import sys
import warnings
from types import FrameType


class SmplcoreError(Exception):
    """The base class of every error smplcore raises on purpose (``except smplcore.errors.SmplcoreError``).

    Each subclass is also the built-in type it used to be (``ValueError``, ``ImportError``, ...)."""


class ModelFileError(SmplcoreError, ValueError):
    """A model file is missing, unsafe, truncated, or does not hold what its model type needs.

    The message names the file and, where one is at fault, the key with the expected and the
    found shape.
    """

    def __init__(self, path: object, message: str, *, key: str | None = None) -> None:
        self.path = str(path)
        self.key = key
        where = f"{self.path}" + (f" [key {key!r}]" if key else "")
        super().__init__(f"{where}: {message}")


class ShapeError(SmplcoreError, ValueError):
    """An argument has the wrong shape; the message names the argument, the expected and the found shape."""


def check_shape(name: str, shape: tuple[int, ...], expected: str, ok: bool) -> None:
    """Raise :class:`ShapeError` for argument ``name`` unless ``ok``."""
    if not ok:
        raise ShapeError(f"{name}: expected shape {expected}, got {tuple(shape)}")


_PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__)) + os.sep
# frames between the caller and smplcore that are not the caller's code: torch's Module.__call__ and
# decorators (inference_mode, no_grad)
_WRAPPER_DIRS = tuple(os.sep + os.path.join("torch", d) + os.sep for d in ("nn", "utils", "autograd"))


def _internal(filename: str) -> bool:
    return filename.startswith(_PACKAGE_DIR) or any(d in filename for d in _WRAPPER_DIRS)


def warn(message: str | Warning, category: type[Warning] = UserWarning) -> None:
    """``warnings.warn`` attributed to the caller's line: the first frame outside smplcore."""
    frame: FrameType | None = sys._getframe(1)
    level = 2
    while frame is not None and _internal(frame.f_code.co_filename):
        frame = frame.f_back
        level += 1
    warnings.warn(message, category, stacklevel=level)
