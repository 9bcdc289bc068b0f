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


# Regressed joints weigh this share of their part's points in the initial rotations (see anchor_weights);
# bones shorter than _ANCHOR_BONE (metres) weigh less, in proportion to their length².
_ANCHOR = 0.05
_ANCHOR_BONE = 0.1


def anchor_weights(body: FitBody, pts: Points, weights: np.ndarray) -> np.ndarray:
    """(J, B) weight of the regressed joints (the ends of each part's bones) in each part's rotation:
    ``_ANCHOR`` of the part's own weight (enough to settle the parts whose points are few or blended, such
    as the collars of a smoothly skinned model, little enough not to disturb the others), times a trust
    that falls with the square of the shortest bone below ``_ANCHOR_BONE`` (a regressed joint is good to a
    few millimetres, a finger bone is a few centimetres long)."""
    share = part_membership(body, pts) @ weights.T  # (J, B)
    bone = np.linalg.norm(body.joint_template - body.joint_template[np.maximum(body.parents, 0)], axis=1)
    bone = np.where(body.parents >= 0, bone, np.inf)
    shortest = np.array(
        [min([bone[j]] + [bone[c] for c in np.flatnonzero(body.parents == j)]) for j in range(len(bone))]
    )
    trust = np.minimum(1.0, (shortest / _ANCHOR_BONE) ** 2)
    return _ANCHOR * np.maximum(share, 1.0) * trust[:, None]


def part_membership(body: FitBody, pts: Points) -> np.ndarray:
    """(J, n): the weight of each point in each part (each point belongs to the joint that moves it most,
    with that joint's skinning weight)."""

    def build() -> np.ndarray:
        membership = np.zeros((body.num_joints, len(pts.ids)))
        membership[pts.joints[:, 0], np.arange(len(pts.ids))] = pts.weights[:, 0]
        return membership

    return body.cached(("membership", pts.ids.tobytes()), build)


def _bones(body: FitBody) -> np.ndarray:
    """(J, J): ``[j, a]`` = 1 when joint ``a`` is joint ``j`` or one of its children (the joints that part
    ``j``'s rigid motion carries)."""
    bones = np.eye(body.num_joints)
    for a, p in enumerate(body.parents):
        if p >= 0:
            bones[p, a] = 1.0
    return bones


def part_rotations(
    body: FitBody,
    pts: Points,
    rest: np.ndarray,
    targets: np.ndarray,
    weights: np.ndarray,
    anchors: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
):
    """World rotation (B, J, 3, 3) of each part and whether it was determined (B, J), from (n, 3, B) rest
    points and targets (batch last) and (n, B) weights; ``anchors``: (J, 3, B) rest joints, their (J, 3, B)
    targets and (J, B) weights, added to the part of each joint and of its parent (a bone's direction fixes
    the parts whose own points are few or blended)."""
    n, batch = weights.shape
    membership = part_membership(body, pts).astype(rest.dtype)  # (J, n)
    wt = targets * weights[:, None, :]
    outer = (wt[:, :, None, :] * rest[:, None, :, :]).reshape(n, 9 * batch)  # Σ over points of w t sᵀ
    sums = np.concatenate([outer, wt.reshape(n, -1), (rest * weights[:, None]).reshape(n, -1), weights], axis=1)
    parts = (membership @ sums).astype(np.float64)  # (J, (9 + 3 + 3 + 1) B): one product for every sum
    if anchors is not None:  # per part, the sums over its bones' ends, each with the part's weight
        a_rest, a_target, a_weight = anchors  # (J, 3, B), (J, 3, B), (J_part, B)
        num = len(a_rest)
        outer_a = (a_target[:, :, None] * a_rest[:, None]).reshape(num, 9, batch)
        ones = np.ones((num, 1, batch))
        per_joint = np.concatenate([outer_a, a_target, a_rest, ones], axis=1)  # (J, 16, B)
        parts += np.einsum("ja,jb,akb->jkb", _bones(body), a_weight, per_joint).reshape(num, -1)
    num_joints = body.num_joints
    moments = np.moveaxis(parts[:, : 9 * batch].reshape(num_joints, 3, 3, batch), -1, 0)
    target_sum = np.moveaxis(parts[:, 9 * batch : 12 * batch].reshape(num_joints, 3, batch), -1, 0)
    source_sum = np.moveaxis(parts[:, 12 * batch : 15 * batch].reshape(num_joints, 3, batch), -1, 0)
    total = parts[:, 15 * batch :].T
    rot, strength = _rotations_from_moments(moments, target_sum, source_sum, total)
    return rot, strength > 1e-6


def initialize(
    body: FitBody,
    obj: Objective,
    state: State,
    *,
    iterations: int = 3,
    dtype: npt.DTypeLike = np.float64,
    joints: np.ndarray | None = None,
) -> State:
    """Alternate per-part Procrustes rotations and a linear solve for the shape and translation.

    ``state`` gives the starting shape (and the pose of undetermined parts); returns a new state.
    Products over the points run in ``dtype``. ``joints``: (B, J, 3) estimates of the posed skeleton
    joints (e.g. the joint regressor applied to target vertices), which join each part's rotation as
    the ends of its bones (weighted by :func:`anchor_weights`).
    """
    pts = obj.points
    state = state.copy()
    parents = body.parents
    arrays = dense.dense_points(body, pts, dtype)
    targets = np.ascontiguousarray(np.moveaxis(obj.targets, 0, -1), dtype=arrays.dtype)  # (n, 3, B)
    weights = np.ascontiguousarray(obj.weights.T, dtype=arrays.dtype)  # (n, B)
    anchor_target = anchor_weight = None
    if joints is not None:
        anchor_target = np.ascontiguousarray(np.moveaxis(joints, 0, -1))  # (J, 3, B)
        anchor_weight = anchor_weights(body, pts, obj.weights)
    for _ in range(iterations):
        theta = body.full_pose(state.pose)
        posed = dense.pose(body, arrays, theta, state.coeffs, state.transl)
        anchors = None
        if anchor_target is not None and anchor_weight is not None:
            rest_joints = body.joint_template + np.einsum("jck,bk->bjc", body.joint_shape, state.coeffs)
            anchors = (np.moveaxis(rest_joints, 0, -1), anchor_target, anchor_weight)
        world, known = part_rotations(body, pts, posed.rest, targets, weights, anchors)
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
    if obj.shape_prior and k:
        hess[:, np.arange(k), np.arange(k)] += obj.shape_prior
        grad[:, :k] += obj.shape_prior * state.coeffs[:, free]
    shared = np.zeros(size, bool)
    shared[:k] = obj.shared[free]
    if batch == 1:
        shared[:] = False
    step = _step(hess, grad, np.full(batch, 1e-9), shared)
    state.coeffs[:, free] += step[:, :k]
    if obj.fit_transl:
        state.transl += step[:, k:]
    return state
