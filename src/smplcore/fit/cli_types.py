"""Argument types of ``smplcore fit``: each parses one option's text or raises ``argparse.ArgumentTypeError``
with what was expected (so a bad value exits 2 before any fit starts)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np


def _floats(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(v) for v in text.replace(",", " ").split())
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers separated by commas, got {text!r}") from None


def _positive_floats(text: str) -> tuple[float, ...]:
    values = _floats(text)
    if not values or not all(np.isfinite(v) and v > 0 for v in values):
        raise argparse.ArgumentTypeError(f"expected positive numbers (pixels), got {text!r}")
    return values


def _weights(text: str) -> tuple[float, ...]:
    values = _floats(text)
    if not values or not all(np.isfinite(v) and v >= 0 for v in values):
        raise argparse.ArgumentTypeError(f"expected non-negative numbers, one per joint, got {text!r}")
    return values


def _extrinsics(text: str) -> tuple[float, ...]:
    """A world-to-camera matrix: 12 or 16 numbers (3 x 4 or 4 x 4, row by row), or a .npy / text file of it."""
    path = Path(text)
    if path.suffix.lower() in (".npy", ".txt", ".csv") or path.exists():
        if not path.is_file():
            raise argparse.ArgumentTypeError(f"{text}: no such file")
        try:
            values = np.load(path) if path.suffix.lower() == ".npy" else np.loadtxt(path, delimiter=None, ndmin=2)
        except (OSError, ValueError) as exc:
            raise argparse.ArgumentTypeError(f"{text}: cannot read a matrix ({exc})") from None
        flat = np.asarray(values, np.float64).reshape(-1)
    else:
        flat = np.asarray(_floats(text))
    if flat.size not in (12, 16):
        raise argparse.ArgumentTypeError(f"expected a 3 x 4 or 4 x 4 world-to-camera matrix (12 or 16 numbers), got "
                                         f"{flat.size} numbers")  # fmt: skip
    matrix = np.eye(4)
    matrix[: flat.size // 4] = flat.reshape(-1, 4)
    rotation = matrix[:3, :3]
    if (
        not np.all(np.isfinite(matrix))
        or not np.allclose(matrix[3], [0, 0, 0, 1])
        or np.abs(rotation @ rotation.T - np.eye(3)).max() > 1e-5
        or np.linalg.det(rotation) < 0
    ):
        raise argparse.ArgumentTypeError(
            "expected a rigid world-to-camera transform [R | t] (R a rotation, last row 0 0 0 1), OpenCV axes "
            "(x right, y down, z forward)"
        )
    return tuple(float(v) for v in matrix.reshape(-1))


def _positive(text: str) -> float:
    """A finite number > 0 (``--fps nan`` would write a file the readers refuse)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return value


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected 1 or more, got {value}")
    return value


def _person(text: str) -> int | str:
    """A track number (0 or more) or ``all``."""
    if text.strip().lower() == "all":
        return "all"
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a track number (0, 1, ...) or 'all', got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a track number (0, 1, ...) or 'all', got {text!r}")
    return value


def _skeleton(text: str) -> str:
    """A known skeleton map's name (``smplcore.skeletons.skeleton_names()``)."""
    from smplcore import skeletons

    try:
        return skeletons.skeleton_map(text).name
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("skeleton: ")) from None


def _units(text: str) -> str:
    """``cm``, ``m``, ``mm``, ``in``, ``cmu``, ``ft`` or metres per unit."""
    from smplcore import skeletons

    try:
        skeletons.parse_units(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("units: ")) from None
    return text
