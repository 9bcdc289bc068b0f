"""Closed-form initial parameters: per-part rotations by weighted Procrustes, then shape and translation
by linear least squares, alternated (the idea of smplfitter; written for smplcore's fitting arrays).

For fixed local rotations, posed points are affine in the shape coefficients and the translation, so
their least-squares values come from one linear solve; for fixed shape, the world rotation of each
part is the weighted Procrustes (Kabsch) rotation between its rest-pose points and their targets.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from smplcore.engine import rodrigues
from smplcore.fit import dense
from smplcore.fit.body import FitBody, Points
from smplcore.fit.solver import Objective, State, _step


def kabsch(source: np.ndarray, target: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted rotations aligning centred point sets.

    Parameters
    ----------
    source, target : (..., n, 3) points.
    weights : (..., n) non-negative weights.

    Returns
    -------
    rotations : (..., 3, 3) ``R`` minimising Σ w |R (s − s̄) − (t − t̄)|².
    strength : (...,) the two largest singular values' smaller one (≈ 0: the rotation is undetermined).
    """
    total = weights.sum(-1)
    moments = np.einsum("...n,...nc,...nd->...cd", weights, target, source)
    return _rotations_from_moments(
        moments, np.einsum("...n,...nc->...c", weights, target), np.einsum("...n,...nc->...c", weights, source), total
    )


def _rotations_from_moments(
    moments: np.ndarray, target_sum: np.ndarray, source_sum: np.ndarray, total: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Kabsch from weighted sums: Σ w t sᵀ (..., 3, 3), Σ w t, Σ w s (..., 3) and Σ w (...,)."""
    safe = np.maximum(total, 1e-300)[..., None, None]
    cov = moments - target_sum[..., :, None] * source_sum[..., None, :] / safe
    u, sing, vt = np.linalg.svd(cov)
    sign = np.sign(np.linalg.det(u @ vt))
    sign = np.where(sign == 0, 1.0, sign)
    u = u.copy()
    u[..., :, 2] *= sign[..., None]
    return u @ vt, sing[..., 1] / safe[..., 0, 0]


def rotation_log(rotmats: np.ndarray) -> np.ndarray:
    """(..., 3) axis-angle of (..., 3, 3) rotation matrices (angles in [0, π])."""
    flat = rotmats.reshape(-1, 3, 3)
    return Rotation.from_matrix(flat).as_rotvec().reshape(*rotmats.shape[:-2], 3)


def part_rotations(body: FitBody, pts: Points, rest: np.ndarray, targets: np.ndarray, weights: np.ndarray):
    """World rotation (B, J, 3, 3) of each part and whether it was determined (B, J)."""
    n = len(pts.ids)
    membership = np.zeros((n, body.num_joints))
    for m in range(pts.joints.shape[1]):
        np.add.at(membership, (np.arange(n), pts.joints[:, m]), pts.weights[:, m])
    membership = np.where(membership >= 0.5, membership, 0.0)  # a part: the points it mostly moves
    w = membership.T[None] * weights[:, None, :]  # (B, J, n)
    outer = (targets[..., :, None] * rest[..., None, :]).reshape(len(rest), n, 9)
    moments = (w @ outer).reshape(len(rest), body.num_joints, 3, 3)  # per part Σ w t sᵀ, one product
    rot, strength = _rotations_from_moments(moments, w @ targets, w @ rest, w.sum(-1))
    return rot, strength > 1e-6


def initialize(body: FitBody, obj: Objective, state: State, *, iterations: int = 3) -> State:
    """Alternate per-part Procrustes rotations and a linear solve for the shape and translation.

    ``state`` gives the starting shape (and the pose of undetermined parts); returns a new state.
    """
    pts = obj.points
    batch = len(state.pose)
    state = state.copy()
    parents = body.parents
    for _ in range(iterations):
        theta = body.full_pose(state.pose)
        rot = rodrigues(theta)
        rest = pts.template + np.einsum("nck,bk->bnc", pts.shape, state.coeffs)
        if pts.posedirs is not None:
            feats = (rot[:, 1:] - np.eye(3)).reshape(batch, body.num_joints - 1, 9)
            rest = rest + np.einsum("ncjf,bjf->bnc", pts.posedirs, feats)
        world, known = part_rotations(body, pts, rest, obj.targets, obj.weights)
        # a part without enough points keeps its current local rotation
        current_world = np.empty_like(rot)
        for j in body.tree.order:
            p = parents[j]
            if p >= 0:
                current_world[:, j] = current_world[:, p] @ rot[:, j]
            else:
                current_world[:, j] = rot[:, j]
            current_world[:, j] = np.where(known[:, j, None, None], world[:, j], current_world[:, j])
        local = np.empty_like(rot)
        for j in body.tree.order:
            p = parents[j]
            parent_world = np.eye(3) if p < 0 else np.swapaxes(current_world[:, p], -1, -2)
            local[:, j] = parent_world @ current_world[:, j]
        state.pose = body.pose_from_full(rotation_log(local))
        state = shape_and_translation(body, obj, state)
    return state


def shape_and_translation(body: FitBody, obj: Objective, state: State) -> State:
    """The least-squares shape coefficients and translation for the state's rotations (exact: the posed
    points are affine in them), from one linear solve on those columns (shape prior included)."""
    free = np.flatnonzero(obj.free_coeffs)
    if not (len(free) or obj.fit_transl):
        return state
    state = state.copy()
    batch = len(state.pose)
    arrays = dense.dense_points(body, obj.points)
    posed = dense.pose(body, arrays, body.full_pose(state.pose), state.coeffs, state.transl)
    n = arrays.count
    blocks = [np.moveaxis(dense.coefficient_jacobian(body, obj.points, arrays, posed)[:, :, free], -1, 0)]
    if obj.fit_transl:
        blocks.append(np.broadcast_to(np.eye(3), (batch, n, 3, 3)))
    jac = np.concatenate(blocks, axis=-1).reshape(batch, 3 * n, -1)  # (B, 3 n, K' + 3)
    sw = np.sqrt(np.repeat(obj.weights, 3, axis=1))[..., None]
    res = np.moveaxis(posed.points - np.moveaxis(obj.targets, 0, -1), -1, 0).reshape(batch, 3 * n, 1)
    jw = jac * sw
    hess = np.matmul(np.swapaxes(jw, 1, 2), jw)
    grad = np.matmul(np.swapaxes(jw, 1, 2), res * sw)[..., 0]
    if obj.shape_prior:
        k = len(free)
        hess[:, np.arange(k), np.arange(k)] += obj.shape_prior
        grad[:, :k] += obj.shape_prior * state.coeffs[:, free]
    shared = np.zeros(hess.shape[1], bool)
    shared[: len(free)] = obj.shared[free]
    if batch == 1:
        shared[:] = False
    step = _step(hess, grad, np.full(batch, 1e-9), shared)
    state.coeffs[:, free] += step[:, : len(free)]
    if obj.fit_transl:
        state.transl += step[:, len(free) :]
    return state
