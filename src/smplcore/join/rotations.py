"""Rotation helpers of :mod:`smplcore.join`: parsing axis-angle or matrices, the left/right mirror, angles."""

from __future__ import annotations

from typing import Any

import numpy as np

from smplcore.engine.reference import rotation_quaternions
from smplcore.engine.rotations import quat_to_rotvec, rodrigues
from smplcore.errors import ShapeError

#: The mirror x -> -x (of a hand model's own frame, or of a camera's image x axis).
MIRROR = np.diag([-1.0, 1.0, 1.0])
#: Axis-angle of a mirrored rotation: ``log(M R M) = (x, -y, -z)`` for ``log R = (x, y, z)``.
MIRROR_AXIS_ANGLE = np.array([1.0, -1.0, -1.0])


def numpy_of(value: Any) -> Any:
    """``value`` as a float64 NumPy array (torch tensors on any device, with or without grad, included); None
    stays None."""
    if value is None:
        return None
    if hasattr(value, "detach") and hasattr(value, "cpu"):
        value = value.detach().cpu().numpy()
    return np.asarray(value, dtype=np.float64)


def to_matrix(rotvec: np.ndarray) -> np.ndarray:
    """(..., 3) axis-angle to (..., 3, 3) rotation matrices (float64)."""
    return rodrigues(np.asarray(rotvec, dtype=np.float64))


def to_axis_angle(rotmats: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices to (..., 3) axis-angle, angles in [0, π]."""
    rotmats = np.asarray(rotmats, dtype=np.float64)
    return quat_to_rotvec(rotation_quaternions(rotmats))


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(...,) angle in radians of ``aᵀ b`` for (..., 3, 3) rotations (0 when equal)."""
    rel = np.swapaxes(a, -1, -2) @ b
    return np.linalg.norm(to_axis_angle(rel), axis=-1)


def as_rotations(name: str, value: Any, num_joints: int) -> np.ndarray:
    """``value`` as (B, num_joints, 3, 3) rotation matrices.

    Axis-angle is 1-D (3 n,) or 2-D (B, 3 n); rotation matrices are 3-D (B, 3, 3) when n = 1 or (n, 3, 3) for
    one body, or 4-D (B, n, 3, 3). A 2-D (3, 3) array is read as three axis-angle rows (pass one matrix as
    (1, 3, 3)).
    """
    a = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: contains NaN or inf values")
    n = num_joints
    if a.ndim in (3, 4) and a.shape[-2:] == (3, 3):
        if a.ndim == 3:
            a = a[:, None] if n == 1 else a[None]
        if a.shape[1] != n:
            raise ShapeError(
                f"{name}: expected rotation matrices of shape (B, {n}, 3, 3), got {tuple(np.shape(value))}"
            )
        return a
    if a.ndim == 1:
        a = a[None]
    if a.ndim != 2 or a.shape[1] != 3 * n:
        raise ShapeError(
            f"{name}: expected axis-angle of shape (B, {3 * n}) or rotation matrices (B, {n}, 3, 3), "
            f"got {tuple(np.shape(value))}"
        )
    return to_matrix(a.reshape(a.shape[0], n, 3))


def mirror_axis_angle(pose: np.ndarray) -> np.ndarray:
    """(..., 3 n) axis-angle of joints mirrored through x -> -x: every (x, y, z) becomes (x, -y, -z)."""
    pose = np.asarray(pose, dtype=np.float64)
    return (pose.reshape(*pose.shape[:-1], -1, 3) * MIRROR_AXIS_ANGLE).reshape(pose.shape)


def mirror_matrix(rotmats: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations mirrored through x -> -x: ``M R M``."""
    return MIRROR @ np.asarray(rotmats, dtype=np.float64) @ MIRROR


def twist_angle(rotmats: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """(...,) signed angle of the twist of (..., 3, 3) rotations about the unit ``axis`` (3,) or (..., 3),
    from the swing-twist split (the same for ``R = swing twist`` and ``R = twist swing``), in (-π, π]."""
    q = rotation_quaternions(np.asarray(rotmats, dtype=np.float64))
    q = np.where(q[..., :1] < 0, -q, q)
    along = np.sum(q[..., 1:] * axis, axis=-1)
    return 2.0 * np.arctan2(along, q[..., 0])
