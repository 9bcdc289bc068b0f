"""Closed-form initial parameters: per-part rotations by weighted Procrustes, then shape and translation
by linear least squares, alternated (the idea of smplfitter; written for smplcore's fitting arrays).

For fixed local rotations, posed points are affine in the shape coefficients and the translation, so
their least-squares values come from one linear solve; for fixed shape, each part turns by the weighted
Procrustes (Kabsch) rotation between its currently posed points and their targets.
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
# ... and half as much each round: near the answer they only bias it (on a posed smoothly skinned mesh the
# regressed joints are up to ~1 cm from the skeleton's), while the points are exact.
_ANCHOR_DECAY = 0.5
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
    source: np.ndarray,
    targets: np.ndarray,
    weights: np.ndarray,
    anchors: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
):
    """The rotation (B, J, 3, 3) that best turns each part's points onto their targets (about their
    centroids) and whether it was determined (B, J), from (n, 3, B) ``source`` points and targets (batch
    last) and (n, B) weights; ``anchors``: (J, 3, B) source joints, their (J, 3, B) targets and (J, B)
    weights, added to the part of each joint and of its parent (a bone's direction fixes the parts whose
    own points are few or blended)."""
    n, batch = weights.shape
    membership = part_membership(body, pts).astype(source.dtype)  # (J, n)
    wt = targets * weights[:, None, :]
    outer = (wt[:, :, None, :] * source[:, None, :, :]).reshape(n, 9 * batch)  # Σ over points of w t sᵀ
    sums = np.concatenate([outer, wt.reshape(n, -1), (source * weights[:, None]).reshape(n, -1), weights], axis=1)
    parts = (membership @ sums).astype(np.float64)  # (J, (9 + 3 + 3 + 1) B): one product for every sum
    if anchors is not None:  # per part, the sums over its bones' ends, each with the part's weight
        a_source, a_target, a_weight = anchors  # (J, 3, B), (J, 3, B), (J_part, B)
        num = len(a_source)
        outer_a = (a_target[:, :, None] * a_source[:, None]).reshape(num, 9, batch)
        ones = np.ones((num, 1, batch))
        per_joint = np.concatenate([outer_a, a_target, a_source, ones], axis=1)  # (J, 16, B)
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

    Each round rotates every part by the Procrustes rotation from its currently posed points (skinned, pose
    correctives included) to their targets, so that the exact parameters are a fixed point even where a
    part's points are blended with its neighbours'; then solves the shape and translation for those
    rotations. Each body keeps the state of lowest cost over the rounds (a round can overshoot where the
    shape absorbs a blended part's misfit). ``state`` gives the starting shape (and the pose of
    undetermined parts); returns a new state. Products over the points run in ``dtype``. ``joints``:
    (B, J, 3) estimates of the posed skeleton joints (e.g. the joint regressor applied to target vertices),
    which join each part's rotation as the ends of its bones (weighted by :func:`anchor_weights`, halved
    every round: they are good to a few millimetres, the points exactly).
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
    best, best_cost = state.copy(), np.full(len(state.pose), np.inf)

    def keep_best(points: np.ndarray) -> None:
        """Remember the bodies whose state (posed as ``points``) has the lowest cost yet."""
        diff = points - targets
        cost = np.einsum("nb,ncb,ncb->b", weights, diff, diff, dtype=np.float64)
        better = np.flatnonzero(cost < best_cost)
        best.put(better, state.take(better))
        best_cost[better] = cost[better]

    posed = dense.pose(body, arrays, body.full_pose(state.pose), state.coeffs, state.transl)
    keep_best(posed.points)
    for round_ in range(iterations):
        if round_:
            posed = dense.pose(body, arrays, body.full_pose(state.pose), state.coeffs, state.transl)
        anchors = None
        if anchor_target is not None and anchor_weight is not None:
            posed_joints = np.moveaxis(posed.pos + state.transl[:, None], 0, -1)  # (J, 3, B)
            anchors = (posed_joints, anchor_target, anchor_weight * _ANCHOR_DECAY**round_)
        turn, known = part_rotations(body, pts, posed.points, targets, weights, anchors)
        # a part without enough points keeps its current local rotation
        rot = posed.rot
        current_world = np.where(known[..., None, None], turn @ posed.world, posed.world)
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
        state, points = _solve_shape_and_translation(body, obj, state, arrays, targets, weights)
        keep_best(points)
    return best


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
    if arrays is None:
        arrays = dense.dense_points(body, obj.points)
    if targets is None:
        targets = np.moveaxis(obj.targets, 0, -1).astype(arrays.dtype)
    if weights is None:
        weights = obj.weights.T.astype(arrays.dtype)
    return _solve_shape_and_translation(body, obj, state, arrays, targets, weights)[0]


def _solve_shape_and_translation(
    body: FitBody,
    obj: Objective,
    state: State,
    arrays: dense.DensePoints,
    targets: np.ndarray,
    weights: np.ndarray,
) -> tuple[State, np.ndarray]:
    """:func:`shape_and_translation`, and the points (n, 3, B) posed by the new state (from the old ones
    and the step, exactly: the rotations are unchanged)."""
    posed = dense.pose(body, arrays, body.full_pose(state.pose), state.coeffs, state.transl)
    free = np.flatnonzero(obj.free_coeffs)
    if not (len(free) or obj.fit_transl):
        return state, posed.points
    state = state.copy()
    batch = len(state.pose)
    k = len(free)
    size = k + 3 if obj.fit_transl else k
    hess = np.zeros((batch, size, size))
    grad = np.zeros((batch, size))
    res = (posed.points - targets) * weights[:, None]  # (n, 3, B) weighted residuals
    if k:
        cj = dense.coefficient_jacobian_by_body(arrays, posed)  # (B, n, 3, K)
        if k < cj.shape[-1]:
            cj = cj[..., free]
        n = arrays.count
        flat = cj.reshape(batch, 3 * n, k)
        cw = flat * np.sqrt(np.repeat(weights.T, 3, axis=1))[:, :, None]  # (B, 3 n, K')
        hess[:, :k, :k] = np.swapaxes(cw, 1, 2) @ cw
        res_t = np.ascontiguousarray(np.moveaxis(res, -1, 0)).reshape(batch, 1, 3 * n)
        grad[:, :k] = (res_t @ flat)[:, 0]
        if obj.fit_transl:
            hess[:, :k, k:] = np.einsum("bnck,nb->bkc", cj, weights)
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
    points = posed.points
    if k:  # the shape's move of every point: one product per body
        move = (flat @ step[:, :k, None].astype(flat.dtype)).reshape(batch, -1, 3)
        points = points + np.moveaxis(move, 0, -1)
    if obj.fit_transl:
        state.transl += step[:, k:]
        points = points + step[:, k:].T.astype(points.dtype)
    return state, points
