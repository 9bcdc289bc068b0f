"""Rotations: axis-angle to matrix (Rodrigues), axis-angle to and from quaternions, and the pose-corrective
features."""

from __future__ import annotations

from typing import Any

import numpy as np

from smplcore.engine.backend import eye, namespace

# Below this squared angle the Taylor series of the coefficients is used (error < 1e-19 in float64).
_SMALL_ANGLE2 = 1e-6


def rodrigues(rotvec: Any) -> Any:
    """Rotation matrices from axis-angle vectors, exact and smooth everywhere.

    ``R = cos θ I + (sin θ / θ) [r]× + ((1 - cos θ) / θ²) r rᵀ`` with θ = |r|. Near θ = 0 the three
    coefficients come from their Taylor series, and the exact branch never sees θ = 0, so values and
    gradients are finite and correct at zero rotation without adding an epsilon to the norm.

    Parameters
    ----------
    rotvec : (..., 3) axis-angle vectors (NumPy or torch).

    Returns
    -------
    (..., 3, 3) rotation matrices.
    """
    xp = namespace(rotvec)
    x, y, z = rotvec[..., 0], rotvec[..., 1], rotvec[..., 2]
    theta2 = x * x + y * y + z * z
    small = theta2 < _SMALL_ANGLE2
    safe2 = xp.where(small, xp.ones_like(theta2), theta2)
    theta = xp.sqrt(safe2)
    half_sin = xp.sin(theta / 2)
    cos_c = xp.where(small, 1 - theta2 / 2 + theta2 * theta2 / 24, xp.cos(theta))
    sin_c = xp.where(small, 1 - theta2 / 6 + theta2 * theta2 / 120, xp.sin(theta) / theta)
    one_minus_cos_c = xp.where(small, 0.5 - theta2 / 24 + theta2 * theta2 / 720, 2 * half_sin * half_sin / safe2)
    ax, ay, az = sin_c * x, sin_c * y, sin_c * z
    bxy, bxz, byz = one_minus_cos_c * x * y, one_minus_cos_c * x * z, one_minus_cos_c * y * z
    rows = (
        cos_c + one_minus_cos_c * x * x,
        bxy - az,
        bxz + ay,
        bxy + az,
        cos_c + one_minus_cos_c * y * y,
        byz - ax,
        bxz - ay,
        byz + ax,
        cos_c + one_minus_cos_c * z * z,
    )
    return xp.stack(rows, axis=-1).reshape(*rotvec.shape[:-1], 3, 3)


def pose_features(rotmats: Any) -> Any:
    """Pose-corrective features: ``R_j - I`` of every joint but the root, flattened.

    Parameters
    ----------
    rotmats : (B, J, 3, 3) local joint rotations.

    Returns
    -------
    (B, 9 * (J - 1)) features, in the order of the official ``posedirs``.
    """
    batch = rotmats.shape[0]
    return (rotmats[:, 1:] - eye(3, rotmats)).reshape(batch, -1)


def y_angle(rotmat: Any) -> Any:
    """Rotation about Y (radians) of (..., 3, 3) matrices, in an X-Y-Z Euler decomposition."""
    from smplcore.engine.backend import atan2

    xp = namespace(rotmat)
    return atan2(-rotmat[..., 2, 0], xp.sqrt(rotmat[..., 0, 0] ** 2 + rotmat[..., 1, 0] ** 2))


def rotvec_to_quat(rotvec: np.ndarray) -> np.ndarray:
    """(..., 3) axis-angle to (..., 4) unit quaternions (w, x, y, z)."""
    rotvec = np.asarray(rotvec, dtype=np.float64)
    angle = np.linalg.norm(rotvec, axis=-1, keepdims=True)
    half = 0.5 * angle
    small = angle < 1e-8
    # sin(θ/2)/θ, with its Taylor series near zero.
    scale = np.where(small, 0.5 - angle**2 / 48.0, np.sin(half) / np.where(small, 1.0, angle))
    return np.concatenate([np.cos(half), rotvec * scale], axis=-1)


def quat_to_rotvec(quat: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions (w, x, y, z) to (..., 3) axis-angle with angle in [0, π]."""
    quat = np.asarray(quat, dtype=np.float64)
    quat = np.where(quat[..., :1] < 0, -quat, quat)
    w, v = quat[..., :1], quat[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, w)
    small = s < 1e-8
    scale = np.where(small, 2.0 / np.where(w == 0, 1.0, w), angle / np.where(small, 1.0, s))
    return v * scale
