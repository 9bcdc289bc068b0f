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

from smplcore.engine import rodrigues, world_transforms
from smplcore.fit.body import FitBody, Points, right_jacobian, skew


@dataclass(frozen=True)
class DensePoints:
    """Constant arrays of a point set for the products: sparse skinning weights and the blend bases."""

    weights: sp.csr_matrix  # (n, J) skinning weights
    weights_t: sp.csr_matrix  # (J, n)
    template: np.ndarray  # (3 n, 1)
    basis: np.ndarray  # (K + 9 (J - 1), 3 n): shape (and expression) directions, then pose correctives
    basis_t: np.ndarray  # (3 n, K + 9 (J - 1)) contiguous transpose
    subtree: np.ndarray  # (J, J): subtree[k, j] = 1 if joint j is at or below joint k
    num_coeffs: int
    has_pose: bool
    dtype: np.dtype

    @property
    def count(self) -> int:
        return self.weights.shape[0]


def dense_points(body: FitBody, pts: Points, dtype: npt.DTypeLike = np.float64) -> DensePoints:
    """The :class:`DensePoints` of ``pts`` in ``dtype`` (cached on ``body``)."""
    dt = np.dtype(dtype)
    key = ("dense", dt.str, pts.ids.tobytes())
    cached = body._cache.get(key)
    if cached is not None:
        return cached
    n, num_joints = len(pts.ids), body.num_joints
    weights = np.zeros((n, num_joints))
    for m in range(pts.joints.shape[1]):
        np.add.at(weights, (np.arange(n), pts.joints[:, m]), pts.weights[:, m])
    blocks = [pts.shape.reshape(3 * n, -1).T]
    has_pose = pts.posedirs is not None
    if pts.posedirs is not None:
        blocks.append(pts.posedirs.reshape(3 * n, -1).T)
    basis = np.concatenate(blocks, axis=0).astype(dt)
    subtree = np.zeros((num_joints, num_joints))
    for j in range(num_joints):
        subtree[body.tree.chain_to_root(j), j] = 1.0
    arrays = DensePoints(
        weights=sp.csr_matrix(weights.astype(dt)),
        weights_t=sp.csr_matrix(weights.T.astype(dt)),
        template=pts.template.reshape(-1, 1).astype(dt),
        basis=np.ascontiguousarray(basis),
        basis_t=np.ascontiguousarray(basis.T),
        subtree=subtree,
        num_coeffs=pts.shape.shape[-1],
        has_pose=has_pose,
        dtype=dt,
    )
    if len(body._cache) < 32:
        body._cache[key] = arrays
    return arrays


@dataclass
class Posed:
    """Posed points (n, 3, B) and the intermediate arrays the gradient reuses."""

    points: np.ndarray  # (n, 3, B) posed points, translation included
    rest: np.ndarray  # (n, 3, B) shaped and corrected rest points
    blend: np.ndarray  # (n, 3, 3, B) blended world rotations A_i
    theta: np.ndarray  # (B, J, 3)
    rot: np.ndarray  # (B, J, 3, 3) local rotations
    world: np.ndarray  # (B, J, 3, 3)
    pos: np.ndarray  # (B, J, 3) posed joints (before the translation)
    shift: np.ndarray  # (B, J, 3) p_j − G_j j̄_j


def _batch_last(a: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """(B, J, c) → contiguous (J, c B) in ``dtype``."""
    return np.ascontiguousarray(np.moveaxis(a, 0, -1), dtype=dtype).reshape(a.shape[1], -1)


def pose(body: FitBody, arrays: DensePoints, theta: np.ndarray, coeffs: np.ndarray, transl: np.ndarray) -> Posed:
    """Pose the points of ``arrays`` for (B, J, 3) ``theta``, (B, K) ``coeffs``, (B, 3) ``transl``."""
    batch, num_joints = theta.shape[:2]
    n, dtype = arrays.count, arrays.dtype
    rot = rodrigues(theta)
    jrest = body.joint_template + np.einsum("jck,bk->bjc", body.joint_shape, coeffs)
    world, pos = world_transforms(rot, jrest, body.tree)
    shift = pos - (world @ jrest[..., None])[..., 0]
    feats = coeffs
    if arrays.has_pose:
        feats = np.concatenate([coeffs, (rot[:, 1:] - np.eye(3)).reshape(batch, -1)], axis=1)
    rest = (arrays.basis_t @ np.ascontiguousarray(feats.T, dtype=dtype) + arrays.template).reshape(n, 3, batch)
    packed = np.concatenate([world.reshape(batch, num_joints, 9), shift], axis=2)  # (B, J, 12)
    mixed = (arrays.weights @ _batch_last(packed, dtype)).reshape(n, 12, batch)
    blend = mixed[:, :9].reshape(n, 3, 3, batch)
    points = mixed[:, 9:] + np.einsum("ncdb,ndb->ncb", blend, rest) + transl.T.astype(dtype)
    return Posed(points, rest, blend, theta, rot, world, pos, shift)


def _vee(m: np.ndarray) -> np.ndarray:
    """(..., 3) ``ε_cde m_de`` of (..., 3, 3) matrices (twice the axial vector of the skew part)."""
    return np.stack([m[..., 1, 2] - m[..., 2, 1], m[..., 2, 0] - m[..., 0, 2], m[..., 0, 1] - m[..., 1, 0]], -1)


def shape_steps(body: FitBody, world: np.ndarray) -> np.ndarray:
    """(B, J, 3, K) ``T_j``: how the shape coefficients move joint ``j``'s skinning offset."""
    parent = np.maximum(body.parents, 0)
    parent_world = np.where((body.parents >= 0)[None, :, None, None], world[:, parent], np.eye(3))
    steps = (parent_world - world) @ body.joint_shape  # (B, J, 3, K)
    totals = np.empty_like(steps)
    for j in body.tree.order:
        p = body.parents[j]
        totals[:, j] = steps[:, j] if p < 0 else steps[:, j] + totals[:, p]
    return totals


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
    g_local = np.einsum("bjcd,bjc->bjd", posed.world, g_world)
    g_theta = np.einsum("bjcd,bjc->bjd", right_jacobian(posed.theta), g_local)
    if arrays.has_pose:
        jr = right_jacobian(posed.theta[:, 1:])
        dvec = (posed.rot[:, 1:, None] @ skew(np.swapaxes(jr, -1, -2))).reshape(batch, num_joints - 1, 3, 9)
        h = g_basis[:, k:].reshape(batch, num_joints - 1, 9)
        g_theta[:, 1:] += np.einsum("bjaf,bjf->bja", dvec, h)
    g_coeffs = g_basis[:, :k] + np.einsum("bjck,bjc->bk", shape_steps(body, posed.world), r_joint)
    g_transl = residual.sum(0).T.astype(np.float64)
    return np.concatenate([g_theta.reshape(batch, -1), g_coeffs, g_transl], axis=1)


def coefficient_jacobian(body: FitBody, pts: Points | None, arrays: DensePoints, posed: Posed) -> np.ndarray:
    """(n, 3, K, B) derivative of the posed points with respect to the shape coefficients."""
    n, k = arrays.count, arrays.num_coeffs
    shape = arrays.basis[:k].T.reshape(n, 3, k)
    dirs = np.einsum("ncdb,ndk->nckb", posed.blend, shape)
    totals = shape_steps(body, posed.world)  # (B, J, 3, K)
    mixed = (arrays.weights @ _batch_last(totals.reshape(*totals.shape[:2], -1), arrays.dtype)).reshape(n, 3, k, -1)
    return dirs + mixed


def _jacobian_constants(body: FitBody, pts: Points) -> tuple:
    """Per point set: ancestors (n, a) padded with the root, their weights below (n, a, m) and sums (n, a),
    the pose correctives (n, 3, 9 (J - 1)). A padded slot repeats the root's, so that scattering the
    blocks writes the same value twice instead of a zero over a real one."""
    key = ("jac", pts.ids.tobytes())
    cached = body._cache.get(key)
    if cached is not None:
        return cached
    valid = pts.ancestors < body.num_joints
    ancestors = np.where(valid, pts.ancestors, pts.ancestors[:, :1])
    below = np.where(valid[..., None], pts.below, pts.below[:, :1])
    posedirs = None if pts.posedirs is None else pts.posedirs.reshape(len(pts.ids), 3, -1)
    out = (ancestors, np.ascontiguousarray(below), below.sum(-1), posedirs)
    if len(body._cache) < 32:
        body._cache[key] = out
    return out


def jacobian(body: FitBody, pts: Points, posed: Posed) -> np.ndarray:
    """(B, 3 n, 3 J + K + 3) exact Jacobian of the posed points ``pts`` (in the posed arrays' precision), equal to
    :func:`smplcore.fit.body.pose_points`' — built from the ancestors of each point only."""
    batch, num_joints = posed.theta.shape[:2]
    n, k = len(pts.ids), pts.shape.shape[-1]
    ancestors, below, below_sum, posedirs = _jacobian_constants(body, pts)
    f = posed.rest.dtype  # float32 for float32 working arrays: a Gauss-Newton matrix need not be exact
    rest = np.moveaxis(posed.rest, -1, 0)  # (B, n, 3)
    world = posed.world.astype(f)
    moved = world[:, pts.joints] @ rest[:, :, None, :, None]  # (B, n, m, 3, 1)
    moved = moved[..., 0] + posed.shift.astype(f)[:, pts.joints]
    u = np.einsum("nam,bnmc->bnac", below.astype(f), moved)
    u -= below_sum.astype(f)[None, :, :, None] * posed.pos.astype(f)[:, ancestors]
    local = (posed.world @ right_jacobian(posed.theta)).astype(f)[:, ancestors]  # (B, n, a, 3 c, 3 col)
    u0, u1, u2 = u[..., 0, None], u[..., 1, None], u[..., 2, None]
    l0, l1, l2 = local[..., 0, :], local[..., 1, :], local[..., 2, :]  # rows c of the columns col
    blocks = np.stack([l1 * u2 - l2 * u1, l2 * u0 - l0 * u2, l0 * u1 - l1 * u0], axis=-2)  # (B, n, a, c, col)
    width = 3 * num_joints + k + 3
    jac = np.zeros((batch, n, 3, width), f)
    # flat positions of the blocks in jac: body b, point i, row c, column 3 ancestor + col
    offsets = (np.arange(n)[:, None, None, None] * 3 * width + np.arange(3)[None, None, :, None] * width) + (
        3 * ancestors[:, :, None, None] + np.arange(3)[None, None, None, :]
    )  # (n, a, 3, 3)
    flat = (np.arange(batch)[:, None] * (n * 3 * width) + offsets.reshape(1, -1)).reshape(-1)
    jac.reshape(-1)[flat] = blocks.reshape(-1)
    rot = jac[..., : 3 * num_joints].reshape(batch, n, 3, num_joints, 3)
    blend = np.moveaxis(posed.blend, -1, 0)  # (B, n, 3, 3)
    if posedirs is not None:
        jr = right_jacobian(posed.theta[:, 1:])
        dvec = (posed.rot[:, 1:, None] @ skew(np.swapaxes(jr, -1, -2))).reshape(batch, num_joints - 1, 3, 9)
        mixed = (blend @ posedirs.astype(f)).reshape(batch, n * 3, num_joints - 1, 9).transpose(0, 2, 1, 3)
        corr = mixed @ np.swapaxes(dvec, -1, -2).astype(f)  # (B, J - 1, 3 n, 3 a)
        rot[:, :, :, 1:] += np.moveaxis(corr.reshape(batch, num_joints - 1, n, 3, 3), 1, 3)
    totals = shape_steps(body, posed.world).astype(f)  # (B, J, 3, K)
    jac[..., 3 * num_joints : 3 * num_joints + k] = blend @ pts.shape.astype(f) + np.einsum(
        "nm,bnmck->bnck", pts.weights, totals[:, pts.joints]
    )
    jac[..., -3:] = np.eye(3)
    return jac.reshape(batch, 3 * n, -1)
