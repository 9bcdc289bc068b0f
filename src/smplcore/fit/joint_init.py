"""The closed-form start of a joint fit: rotations from the target bones, then shape and translation.

Each joint's world rotation aligns its rest bones to the target directions of the nearest observed joints
below it (Procrustes over two or more, the smallest rotation for one; twist inherited from the parent). A
joint that is not observed itself but has observed joints in two or more branches below it (the pelvis of
a skeleton mapped without one, the spine under a neck and two shoulders) turns by the Procrustes rotation
of those joints about their centroid. Bodies with different joints missing (NaN markers) are started
group by group, each group with the joints it has.
"""

from __future__ import annotations

import numpy as np

from smplcore.engine import rodrigues
from smplcore.fit.body import FitBody
from smplcore.fit.initialize import kabsch, shape_and_translation
from smplcore.fit.rotations import rotation_log
from smplcore.fit.solver import Objective, State

# A Procrustes rotation whose second singular value (per unit weight, m²) is below this is undetermined
# (the points are nearly on a line): the smallest rotation of their mean direction is taken instead.
_WEAK = 1e-8


def smallest_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(..., 3, 3) smallest rotations taking directions ``a`` to ``b`` (..., 3)."""
    a = a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-12)
    b = b / np.maximum(np.linalg.norm(b, axis=-1, keepdims=True), 1e-12)
    axis = np.cross(a, b)
    s = np.linalg.norm(axis, axis=-1)
    angle = np.arctan2(s, np.sum(a * b, axis=-1))
    return rodrigues(axis / np.maximum(s, 1e-12)[..., None] * angle[..., None])


def bone_rotations(body: FitBody, point_ids: np.ndarray, targets: np.ndarray, state: State) -> State:
    """Local rotations aligning each joint's rest bones to the target bones (see the module docstring).

    ``point_ids`` (n,) are the fitted points (into the fitting arrays; skeleton joints after the vertices),
    ``targets`` (B, n, 3) their targets, all present."""
    batch = len(targets)
    jrest = body.joint_template + np.einsum("jck,bk->bjc", body.joint_shape, state.coeffs)
    target_of = {int(p) - body.num_vertices: i for i, p in enumerate(point_ids) if p >= body.num_vertices}
    children: dict[int, list[int]] = {}
    for j, p in enumerate(body.parents):
        if p >= 0:
            children.setdefault(int(p), []).append(j)

    def observed_below(j: int) -> list[int]:
        """The nearest observed joints below ``j`` (one per child branch)."""
        out = []
        for c in children.get(j, []):
            out.extend([c] if c in target_of else observed_below(c))
        return out

    world = np.empty((batch, body.num_joints, 3, 3))
    for j in body.tree.order:
        p = body.parents[j]
        inherited = np.broadcast_to(np.eye(3), (batch, 3, 3)) if p < 0 else world[:, p]
        below = observed_below(j)
        observed = j in target_of
        if not below or (not observed and len(below) < 2):
            world[:, j] = inherited
            continue
        src = np.stack([jrest[:, c] - jrest[:, j] for c in below], axis=1)  # (B, n, 3)
        src = np.einsum("bcd,bnd->bnc", inherited, src)
        ends = np.stack([targets[:, target_of[c]] for c in below], axis=1)
        if observed:  # bones from the joint's own target (the joint is one of the points)
            dst = ends - targets[:, target_of[j]][:, None]
            mean_src, mean_dst = src.mean(1), dst.mean(1)
            zero = np.zeros((batch, 1, 3))
            src, dst = np.concatenate([zero, src], 1), np.concatenate([zero, dst], 1)
        else:  # about the centroids
            dst = ends
            mean_src, mean_dst = src[:, -1] - src.mean(1), dst[:, -1] - dst.mean(1)
        if src.shape[1] >= 3:
            rot, strength = kabsch(src, dst, np.ones(src.shape[:2]))
            rot = np.where((strength > _WEAK)[:, None, None], rot, smallest_rotation(mean_src, mean_dst))
        else:
            rot = smallest_rotation(mean_src, mean_dst)
        world[:, j] = rot @ inherited
    local = np.empty_like(world)
    for j in body.tree.order:
        p = body.parents[j]
        local[:, j] = world[:, j] if p < 0 else np.swapaxes(world[:, p], -1, -2) @ world[:, j]
    state = state.copy()
    state.pose = body.pose_from_full(rotation_log(local))
    return state


def initial_state(body: FitBody, point_ids: np.ndarray, obj: Objective, state: State, rounds: int = 2) -> State:
    """``rounds`` of bone rotations then shape and translation, bodies grouped by the points they have
    (``obj.weights > 0``)."""
    present = obj.weights > 0
    patterns, group = np.unique(present, axis=0, return_inverse=True)
    group = group.reshape(-1)
    state = state.copy()
    for g, pattern in enumerate(patterns):
        rows = np.flatnonzero(group == g)
        part = state.take(rows)
        for _ in range(rounds):
            part = bone_rotations(body, point_ids[pattern], obj.targets[rows][:, pattern], part)
            if len(rows) == len(state.pose):
                part = shape_and_translation(body, obj, part)
            else:
                sub = Objective(**{**obj.__dict__, "targets": obj.targets[rows], "weights": obj.weights[rows]})
                part = shape_and_translation(body, sub, part)
        state.put(rows, part)
    if len(patterns) > 1:
        state = joint_shape_and_translation(body, obj, state)
    return state


def joint_shape_and_translation(body: FitBody, obj: Objective, state: State) -> State:
    """Shape and translation solved again over the whole batch, the shared coefficients first made equal
    (bodies started in groups each have their own)."""
    state = state.copy()
    shared = obj.shared & obj.free_coeffs
    if shared.any() and len(state.coeffs) > 1:
        state.coeffs[:, shared] = state.coeffs[:, shared].mean(0)
    return shape_and_translation(body, obj, state)
