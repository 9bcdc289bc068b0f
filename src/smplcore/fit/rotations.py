"""Rotations for the closed-form fits: the nearest rotation to a moment matrix (Kabsch), vectorised, and
the axis-angle of rotation matrices.

The Kabsch rotation of a cross-covariance ``M`` is the orthogonal polar factor of ``M`` when ``det M > 0``.
It comes from the scaled Newton iteration ``X ← ½ (γ X + X⁻ᵀ / γ)``, ``γ = |det X|^(−1/3)`` (Higham,
*Computing the polar decomposition — with applications*, SIAM J. Sci. Stat. Comput. 7, 1986), written
out entry by entry over all matrices at once: a few dozen array operations per iteration instead of one
LAPACK call per matrix. Matrices that are nearly singular or have a negative determinant (where the
Kabsch rotation flips the smallest singular direction) go to the SVD.
"""

from __future__ import annotations

import numpy as np

from smplcore.engine.reference import rotation_quaternions
from smplcore.engine.rotations import quat_to_rotvec

# Frobenius-normalised moment matrices with a determinant below this go to the SVD (a well-spread
# point set has det ≈ (1/3)^(3/2) ≈ 0.19; a flat or a linear one, 0).
_WELL_CONDITIONED = 1e-4


def _cofactors(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cofactor matrices and determinants of (3, 3, N) matrices (entries first)."""
    a, b, c = x[0]
    d, e, f = x[1]
    g, h, i = x[2]
    cof = np.stack(
        [
            np.stack([e * i - f * h, f * g - d * i, d * h - e * g]),
            np.stack([c * h - b * i, a * i - c * g, b * g - a * h]),
            np.stack([b * f - c * e, c * d - a * f, a * e - b * d]),
        ]
    )
    return cof, a * cof[0, 0] + b * cof[0, 1] + c * cof[0, 2]


def _middle_eigenvalue(s: np.ndarray) -> np.ndarray:
    """The middle eigenvalue of (3, 3, N) symmetric matrices (the trigonometric solution of the cubic)."""
    q = (s[0, 0] + s[1, 1] + s[2, 2]) / 3
    off = s[0, 1] ** 2 + s[0, 2] ** 2 + s[1, 2] ** 2
    p = np.sqrt(np.maximum(((s[0, 0] - q) ** 2 + (s[1, 1] - q) ** 2 + (s[2, 2] - q) ** 2 + 2 * off) / 6, 1e-300))
    shifted = (s - q * np.eye(3)[:, :, None]) / p
    _, det = _cofactors(shifted)
    phi = np.arccos(np.clip(det / 2, -1.0, 1.0)) / 3
    largest = q + 2 * p * np.cos(phi)
    smallest = q + 2 * p * np.cos(phi + 2 * np.pi / 3)
    return 3 * q - largest - smallest


def nearest_rotations(moments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Kabsch rotations of cross-covariances.

    Parameters
    ----------
    moments : (..., 3, 3) ``M = Σ w (t − t̄)(s − s̄)ᵀ``.

    Returns
    -------
    rotations : (..., 3, 3) the rotation ``R`` maximising ``tr(Rᵀ M)`` (minimising Σ w |R s − t|²).
    middle : (...,) the middle singular value of ``M`` (≈ 0: the rotation is undetermined).
    """
    shape = moments.shape[:-2]
    flat = moments.reshape(-1, 3, 3)
    norm = np.sqrt(np.einsum("nij,nij->n", flat, flat))
    x = np.moveaxis(flat / np.maximum(norm, 1e-300)[:, None, None], 0, -1).copy()  # (3, 3, N), |x| = 1
    _, det = _cofactors(x)
    good = det > _WELL_CONDITIONED
    rot = np.empty_like(flat)
    middle = np.empty(len(flat))
    if good.any():
        xg = x[..., good]
        for _ in range(30):
            cof, d = _cofactors(xg)
            gamma = np.abs(d) ** (-1 / 3)
            nxt = 0.5 * (gamma * xg + cof / (gamma * d))
            change = np.abs(nxt - xg).max()
            xg = nxt
            if change < 1e-13:
                break
        sym = np.einsum("jin,jkn->ikn", xg, x[..., good])  # Qᵀ M, symmetric positive definite
        middle[good] = _middle_eigenvalue(0.5 * (sym + np.swapaxes(sym, 0, 1))) * norm[good]
        rot[good] = np.moveaxis(xg, -1, 0)
    if not good.all():
        u, sing, vt = np.linalg.svd(flat[~good])
        sign = np.sign(np.linalg.det(u @ vt))
        u[..., :, 2] *= np.where(sign == 0, 1.0, sign)[..., None]
        rot[~good] = u @ vt
        middle[~good] = sing[..., 1]
    return rot.reshape(*shape, 3, 3), middle.reshape(shape)


def rotation_log(rotmats: np.ndarray) -> np.ndarray:
    """(..., 3) axis-angle of (..., 3, 3) rotation matrices (angles in [0, π]), through their quaternions
    (Shepperd's method, exact near the identity and near half turns alike), all matrices at once."""
    return quat_to_rotvec(rotation_quaternions(rotmats))
