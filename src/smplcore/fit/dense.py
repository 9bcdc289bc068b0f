"""Posed points and the exact gradient of a weighted squared error, by a few large matrix products.

Where :func:`smplcore.fit.body.pose_points` forms the dense Jacobian (B, n, 3, P) — exact, but 3 n P
values per body — this module never does: for the gradient ``Jᵀ r`` of ``Σ_i w_i |x_i − y_i|²`` only
per-joint sums are needed. With the point residuals ``r_i = w_i (x_i − y_i)``, the rest-frame residuals
``q_i = A_iᵀ r_i`` (``A_i = Σ_j W_ij G_j`` the blended rotation) and, per joint ``j``,

    R_j = Σ_i W_ij r_i,    M_j = Σ_i W_ij v̄_i r_iᵀ,    C_j = Σ_i W_ij x_ij × r_i = vee(G_j M_j) + s_j × R_j

(``x_ij = G_j v̄_i + s_j`` the point moved by joint ``j`` alone), the gradient with respect to the local
rotation increment of joint ``k`` is ``G_kᵀ (Σ_{j below k} C_j − p_k × Σ_{j below k} R_j)``, the
pose-corrective and shape parts are ``qᵀ [P S]`` (one product over all points) plus ``Σ_j T_jᵀ R_j`` for
the shape's effect on the joints, and the translation's is ``Σ_i r_i``. Every step is a product of a
(B, ·) matrix with a constant one, or a per-joint 3 × 3 operation: cost O(B n (K + 9 J)) in BLAS.

Arrays over points are laid out batch last, (n, 3, B), so that each product is one matrix product for
the whole batch; they are computed in the working precision of the arrays (float32 for float32 models:
twice the speed, posed points good to ~0.1 µm), per-joint quantities in float64.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from smplcore.fit.body import FitBody, Points
from smplcore.fit.kinematics import Kinematics, kinematics


@dataclass(frozen=True)
class DensePoints:
    """Constant arrays of a point set for the products: sparse skinning weights and the blend bases."""

    weights: sp.csr_matrix  # (n, J) skinning weights
    weights_t: sp.csr_matrix  # (J, n)
    template: np.ndarray  # (3 n, 1)
    basis: np.ndarray  # (K + 9 (J - 1), 3 n): shape (and expression) directions, then pose correctives
    basis_t: np.ndarray  # (3 n, K + 9 (J - 1)) contiguous transpose
    subtree: np.ndarray  # (J, J): subtree[k, j] = 1 if joint j is at or below joint k
    shape_t: np.ndarray  # (n, K, 3) the shape (and expression) directions of each point, transposed
    num_coeffs: int
    has_pose: bool
    dtype: np.dtype

    @property
    def count(self) -> int:
        return self.weights.shape[0]


def dense_points(body: FitBody, pts: Points, dtype: npt.DTypeLike = np.float64) -> DensePoints:
    """The :class:`DensePoints` of ``pts`` in ``dtype`` (cached on ``body``)."""
    dt = np.dtype(dtype)
    return body.cached(("dense", dt.str, pts.ids.tobytes()), lambda: _dense_points(body, pts, dt))


def _dense_points(body: FitBody, pts: Points, dt: np.dtype) -> DensePoints:
    n, num_joints = len(pts.ids), body.num_joints
    weights = np.zeros((n, num_joints))
    for m in range(pts.joints.shape[1]):
        np.add.at(weights, (np.arange(n), pts.joints[:, m]), pts.weights[:, m])
    blocks = [pts.shape.reshape(3 * n, -1).T]
    has_pose = pts.posedirs is not None
    if pts.posedirs is not None:
        blocks.append(pts.posedirs.reshape(3 * n, -1).T)
    basis = np.concatenate(blocks, axis=0).astype(dt)
    return DensePoints(
        weights=sp.csr_matrix(weights.astype(dt)),
        weights_t=sp.csr_matrix(weights.T.astype(dt)),
        template=pts.template.reshape(-1, 1).astype(dt),
        basis=np.ascontiguousarray(basis),
        basis_t=np.ascontiguousarray(basis.T),
        subtree=body.below_of().astype(np.float64),
        shape_t=np.ascontiguousarray(np.swapaxes(pts.shape, 1, 2), dtype=dt),
        num_coeffs=pts.shape.shape[-1],
        has_pose=has_pose,
        dtype=dt,
    )


@dataclass
class Posed:
    """Posed points (n, 3, B), the intermediate arrays the gradient reuses and the bodies' kinematics."""

    points: np.ndarray  # (n, 3, B) posed points, translation included
    rest: np.ndarray  # (n, 3, B) shaped and corrected rest points
    blend: np.ndarray  # (n, 3, 3, B) blended world rotations A_i
    kin: Kinematics

    @property
    def theta(self) -> np.ndarray:  # (B, J, 3)
        return self.kin.theta

    @property
    def rot(self) -> np.ndarray:  # (B, J, 3, 3) local rotations
        return self.kin.rot

    @property
    def world(self) -> np.ndarray:  # (B, J, 3, 3)
        return self.kin.world

    @property
    def pos(self) -> np.ndarray:  # (B, J, 3) posed joints (before the translation)
        return self.kin.pos

    @property
    def shift(self) -> np.ndarray:  # (B, J, 3) p_j − G_j j̄_j
        return self.kin.shift


def _batch_last(a: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """(B, J, c) → contiguous (J, c B) in ``dtype``."""
    return np.ascontiguousarray(np.moveaxis(a, 0, -1), dtype=dtype).reshape(a.shape[1], -1)


def pose(
    body: FitBody,
    arrays: DensePoints,
    theta: np.ndarray,
    coeffs: np.ndarray,
    transl: np.ndarray,
    kin: Kinematics | None = None,
) -> Posed:
    """Pose the points of ``arrays`` for (B, J, 3) ``theta``, (B, K) ``coeffs``, (B, 3) ``transl`` (``kin``:
    their :func:`~smplcore.fit.kinematics.kinematics`, when already computed)."""
    if kin is None:
        kin = kinematics(body, theta, coeffs)
    batch, num_joints = theta.shape[:2]
    n, dtype = arrays.count, arrays.dtype
    feats = coeffs
    if arrays.has_pose:
        feats = np.concatenate([coeffs, (kin.rot[:, 1:] - np.eye(3)).reshape(batch, -1)], axis=1)
    rest = (arrays.basis_t @ np.ascontiguousarray(feats.T, dtype=dtype) + arrays.template).reshape(n, 3, batch)
    packed = np.concatenate([kin.world.reshape(batch, num_joints, 9), kin.shift], axis=2)  # (B, J, 12)
    mixed = (arrays.weights @ _batch_last(packed, dtype)).reshape(n, 12, batch)
    blend = mixed[:, :9].reshape(n, 3, 3, batch)
    points = mixed[:, 9:] + transl.T.astype(dtype)
    for d in range(3):
        points += blend[:, :, d] * rest[:, None, d]
    return Posed(points, rest, blend, kin)


def _vee(m: np.ndarray) -> np.ndarray:
    """(..., 3) ``ε_cde m_de`` of (..., 3, 3) matrices (twice the axial vector of the skew part)."""
    return np.stack([m[..., 1, 2] - m[..., 2, 1], m[..., 2, 0] - m[..., 0, 2], m[..., 0, 1] - m[..., 1, 0]], -1)


def gradient(body: FitBody, arrays: DensePoints, posed: Posed, residual: np.ndarray) -> np.ndarray:
    """(B, 3 J + K + 3) ``Jᵀ r`` over [θ (joint-major axis-angle), coeffs, transl] for (n, 3, B) ``residual``
    (already weighted): ``pose_points(..., jacobian=True)``'s Jacobian transposed times it, in float64."""
    batch, num_joints = posed.theta.shape[:2]
    n, k = arrays.count, arrays.num_coeffs
    q = np.einsum("ncdb,ncb->ndb", posed.blend, residual)  # rest-frame residuals A_iᵀ r_i
    g_basis = (arrays.basis @ q.reshape(3 * n, batch)).T.astype(np.float64)  # (B, K + 9 (J - 1))
    r_joint = (arrays.weights_t @ residual.reshape(n, -1)).reshape(num_joints, 3, batch)
    r_joint = np.moveaxis(r_joint, -1, 0).astype(np.float64)  # (B, J, 3)
    outer = (posed.rest[:, :, None] * residual[:, None]).reshape(n, -1)  # (n, 9 B): v̄_a r_b
    moments = (arrays.weights_t @ outer).reshape(num_joints, 3, 3, batch)
    moments = np.moveaxis(moments, -1, 0).astype(np.float64)  # (B, J, 3, 3)
    c_joint = _vee(posed.world @ moments) + np.cross(posed.shift, r_joint)
    c_sub = arrays.subtree @ c_joint
    r_sub = arrays.subtree @ r_joint
    g_world = c_sub - np.cross(posed.pos, r_sub)  # (B, J, 3) world-axis torque about each joint
    g_theta = np.einsum("bjcd,bjc->bjd", posed.kin.lift, g_world)
    if arrays.has_pose:
        h = g_basis[:, k:].reshape(batch, num_joints - 1, 9)
        g_theta[:, 1:] += np.einsum("bjfa,bjf->bja", posed.kin.slopes, h)
    g_coeffs = g_basis[:, :k] + np.einsum("bjck,bjc->bk", posed.kin.totals, r_joint)
    g_transl = residual.sum(0).T.astype(np.float64)
    return np.concatenate([g_theta.reshape(batch, -1), g_coeffs, g_transl], axis=1)


def coefficient_jacobian(body: FitBody, pts: Points | None, arrays: DensePoints, posed: Posed) -> np.ndarray:
    """(n, 3, K, B) derivative of the posed points with respect to the shape coefficients."""
    n, k = arrays.count, arrays.num_coeffs
    batch = posed.blend.shape[-1]
    # Σ_d A_cd S_dk per point: (n, K, 3 d) @ (n, 3 d, 3 c B), one small product per point
    blend = np.swapaxes(posed.blend, 1, 2).reshape(n, 3, 3 * batch)
    dirs = np.swapaxes((arrays.shape_t @ blend).reshape(n, k, 3, batch), 1, 2).copy()
    totals = posed.kin.totals  # (B, J, 3, K)
    dirs += (arrays.weights @ _batch_last(totals.reshape(*totals.shape[:2], -1), arrays.dtype)).reshape(n, 3, k, -1)
    return dirs


def coefficient_jacobian_by_body(arrays: DensePoints, posed: Posed) -> np.ndarray:
    """(B, n, 3, K) :func:`coefficient_jacobian` laid out body first (each body's (3 n, K) block contiguous,
    for one product per body): the skinning weights times the joints' shape totals (one small product per
    body), plus the blended rotations times each point's shape directions (one product per point)."""
    n, k = arrays.count, arrays.num_coeffs
    totals = posed.kin.totals  # (B, J, 3, K)
    batch = len(totals)
    weights = arrays.weights.toarray()  # (n, J)
    out = np.matmul(weights, totals.reshape(batch, totals.shape[1], 3 * k).astype(arrays.dtype))
    out = out.reshape(batch, n, 3, k)
    blend = np.ascontiguousarray(np.moveaxis(posed.blend, -1, 1)).reshape(n, 3 * batch, 3)  # (n, B c, d)
    out += np.moveaxis((blend @ np.swapaxes(arrays.shape_t, 1, 2)).reshape(n, batch, 3, k), 1, 0)
    return out
