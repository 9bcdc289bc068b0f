"""Exception types raised by smplcore."""

from __future__ import annotations


class ModelFileError(ValueError):
    """A model file is missing, unsafe, truncated, or does not hold what its model type needs.

    The message names the file and, where one is at fault, the key with the expected and the
    found shape.
    """

    def __init__(self, path: object, message: str, *, key: str | None = None) -> None:
        self.path = str(path)
        self.key = key
        where = f"{self.path}" + (f" [key {key!r}]" if key else "")
        super().__init__(f"{where}: {message}")


class ShapeError(ValueError):
    """An argument has the wrong shape; the message names the argument, the expected and the found shape."""


def check_shape(name: str, shape: tuple[int, ...], expected: str, ok: bool) -> None:
    """Raise :class:`ShapeError` for argument ``name`` unless ``ok``."""
    if not ok:
        raise ShapeError(f"{name}: expected shape {expected}, got {tuple(shape)}")
