"""Closed-form initial parameters: per-part rotations by weighted Procrustes, then shape and translation
by linear least squares, alternated (the idea of smplfitter; written for smplcore's fitting arrays).

For fixed local rotations, posed points are affine in the shape coefficients and the translation, so
their least-squares values come from one linear solve; for fixed shape, the world rotation of each
part is the weighted Procrustes (Kabsch) rotation between its rest-pose points and their targets.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from smplcore.fit import dense
from smplcore.fit.body import FitBody, Points
from smplcore.fit.rotations import nearest_rotations, rotation_log
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
    rot, middle = nearest_rotations(cov)
    return rot, middle / safe[..., 0, 0]


def part_membership(body: FitBody, pts: Points) -> np.ndarray:
    """(J, n): the weight of each point in each part (the points a joint moves with at least half the weight)."""

    def build() -> np.ndarray:
        n = len(pts.ids)
        membership = np.zeros((n, body.num_joints))
        for m in range(pts.joints.shape[1]):
            np.add.at(membership, (np.arange(n), pts.joints[:, m]), pts.weights[:, m])
        import os

        pw = float(os.environ.get("MEMB_POW", "1"))
        return np.ascontiguousarray(np.where(membership >= 0.5, membership**pw, 0.0).T)

    return body.cached(("membership", pts.ids.tobytes()), build)


def part_rotations(body: FitBody, pts: Points, rest: np.ndarray, targets: np.ndarray, weights: np.ndarray):
    """World rotation (B, J, 3, 3) of each part and whether it was determined (B, J), from (n, 3, B) rest
    points and targets (batch last) and (n, B) weights."""
    n, batch = weights.shape
    membership = part_membership(body, pts).astype(rest.dtype)  # (J, n)
    wt = targets * weights[:, None, :]
    outer = (wt[:, :, None, :] * rest[:, None, :, :]).reshape(n, 9 * batch)  # Σ over points of w t sᵀ
    sums = np.concatenate([outer, wt.reshape(n, -1), (rest * weights[:, None]).reshape(n, -1), weights], axis=1)
    parts = (membership @ sums).astype(np.float64)  # (J, (9 + 3 + 3 + 1) B): one product for every sum
    num_joints = body.num_joints
    moments = np.moveaxis(parts[:, : 9 * batch].reshape(num_joints, 3, 3, batch), -1, 0)
    target_sum = np.moveaxis(parts[:, 9 * batch : 12 * batch].reshape(num_joints, 3, batch), -1, 0)
    source_sum = np.moveaxis(parts[:, 12 * batch : 15 * batch].reshape(num_joints, 3, batch), -1, 0)
    total = parts[:, 15 * batch :].T
    rot, strength = _rotations_from_moments(moments, target_sum, source_sum, total)
    return rot, strength > 1e-6


def initialize(
    body: FitBody, obj: Objective, state: State, *, iterations: int = 3, dtype: npt.DTypeLike = np.float64
) -> State:
    """Alternate per-part Procrustes rotations and a linear solve for the shape and translation.

    ``state`` gives the starting shape (and the pose of undetermined parts); returns a new state.
    Products over the points run in ``dtype``.
    """
    pts = obj.points
    state = state.copy()
    parents = body.parents
    arrays = dense.dense_points(body, pts, dtype)
    targets = np.ascontiguousarray(np.moveaxis(obj.targets, 0, -1), dtype=arrays.dtype)  # (n, 3, B)
    weights = np.ascontiguousarray(obj.weights.T, dtype=arrays.dtype)  # (n, B)
    for _ in range(iterations):
        theta = body.full_pose(state.pose)
        posed = dense.pose(body, arrays, theta, state.coeffs, state.transl)
        world, known = part_rotations(body, pts, posed.rest, targets, weights)
        # a part without enough points keeps its current local rotation
        rot = posed.rot
        current_world = np.where(known[..., None, None], world, posed.world)
        local = np.empty_like(rot)
        for j in body.tree.order:
            p = parents[j]
            if p >= 0 and not known[:, j].all():  # undetermined: follow the (new) parent
                current_world[:, j] = np.where(
                    known[:, j, None, None], current_world[:, j], current_world[:, p] @ rot[:, j]
                )
            parent_world = np.eye(3) if p < 0 else np.swapaxes(current_world[:, p], -1, -2)
            local[:, j] = parent_world @ current_world[:, j]
        state.pose = body.pose_from_full(rotation_log(local))
        state = shape_and_translation(body, obj, state, arrays=arrays, targets=targets, weights=weights)
    return state


def shape_and_translation(
    body: FitBody,
    obj: Objective,
    state: State,
    *,
    arrays: dense.DensePoints | None = None,
    targets: np.ndarray | None = None,
    weights: np.ndarray | None = None,
) -> State:
    """The least-squares shape coefficients and translation for the state's rotations (exact: the posed
    points are affine in them), from one linear solve on those columns (shape prior included).
    ``arrays``, ``targets`` (n, 3, B) and ``weights`` (n, B) can be given in the working precision."""
    free = np.flatnonzero(obj.free_coeffs)
    if not (len(free) or obj.fit_transl):
        return state
    state = state.copy()
    batch = len(state.pose)
    if arrays is None:
        arrays = dense.dense_points(body, obj.points)
    if targets is None:
        targets = np.moveaxis(obj.targets, 0, -1).astype(arrays.dtype)
    if weights is None:
        weights = obj.weights.T.astype(arrays.dtype)
    posed = dense.pose(body, arrays, body.full_pose(state.pose), state.coeffs, state.transl)
    k = len(free)
    size = k + 3 if obj.fit_transl else k
    hess = np.zeros((batch, size, size))
    grad = np.zeros((batch, size))
    res = (posed.points - targets) * weights[:, None]  # (n, 3, B) weighted residuals
    if k:
        cj = dense.coefficient_jacobian(body, obj.points, arrays, posed)  # (n, 3, K, B)
        if k < cj.shape[2]:
            cj = cj[:, :, free]
        cw = cj * np.sqrt(weights)[:, None, None, :]
        flat = np.ascontiguousarray(np.moveaxis(cw, -1, 0)).reshape(batch, -1, k)  # (B, 3 n, K')
        hess[:, :k, :k] = np.swapaxes(flat, 1, 2) @ flat
        grad[:, :k] = np.einsum("nckb,ncb->bk", cj, res)
        if obj.fit_transl:
            hess[:, :k, k:] = np.einsum("nckb,nb->bkc", cj, weights)
            hess[:, k:, :k] = np.swapaxes(hess[:, :k, k:], 1, 2)
    if obj.fit_transl:
        hess[:, k:, k:] = weights.sum(0)[:, None, None] * np.eye(3)
        grad[:, k:] = res.sum(0).T
    import os

    extra = float(os.environ.get("INIT_PRIOR", "0")) * weights.sum(0)[:, None]
    if (obj.shape_prior or extra.any()) and k:
        hess[:, np.arange(k), np.arange(k)] += obj.shape_prior + extra
        grad[:, :k] += (obj.shape_prior + extra) * state.coeffs[:, free]
    shared = np.zeros(size, bool)
    shared[:k] = obj.shared[free]
    if batch == 1:
        shared[:] = False
    step = _step(hess, grad, np.full(batch, 1e-9), shared)
    state.coeffs[:, free] += step[:, :k]
    if obj.fit_transl:
        state.transl += step[:, k:]
    return state
