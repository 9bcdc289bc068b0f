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
from smplcore.fit.body import FitBody, Points
from smplcore.fit.solver import Objective, State, _step, normal_equations


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
    total = np.maximum(weights.sum(-1, keepdims=True), 1e-300)
    sc = source - np.einsum("...n,...nc->...c", weights, source)[..., None, :] / total[..., None]
    tc = target - np.einsum("...n,...nc->...c", weights, target)[..., None, :] / total[..., None]
    cov = np.einsum("...n,...nc,...nd->...cd", weights, tc, sc)
    u, sing, vt = np.linalg.svd(cov)
    sign = np.sign(np.linalg.det(u @ vt))
    sign = np.where(sign == 0, 1.0, sign)
    u = u.copy()
    u[..., :, 2] *= sign[..., None]
    return u @ vt, sing[..., 1] / np.maximum(total[..., 0], 1e-300)


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
    w = np.einsum("nj,bn->bjn", membership, weights)
    rot, strength = kabsch(rest[:, None], targets[:, None], w)
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
    points are affine in them), by one Gauss–Newton step on those columns."""
    if not (obj.free_coeffs.any() or obj.fit_transl):
        return state
    state = state.copy()
    batch, q = len(state.pose), body.num_pose
    lin_obj = Objective(**{**obj.__dict__, "pose_prior": None, "pose_mean": None})
    hess, grad, _ = normal_equations(body, lin_obj, state)
    assert hess is not None  # asked for
    keep = np.arange(q, hess.shape[1])
    hess, grad = hess[:, keep][:, :, keep], grad[:, keep]
    cols = np.flatnonzero(obj.free_coeffs)
    shared = np.zeros(len(keep), bool)
    shared[: len(cols)] = obj.shared[cols]
    if batch == 1:
        shared[:] = False
    step = _step(hess, grad, np.full(batch, 1e-9), shared)
    state.coeffs[:, cols] += step[:, : len(cols)]
    if obj.fit_transl:
        state.transl += step[:, len(cols) :]
    return state
