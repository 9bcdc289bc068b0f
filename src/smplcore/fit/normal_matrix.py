"""The Gauss–Newton matrix ``Jᵀ W J`` of posed points, built part by part.

A posed point depends on the rotations of the joints above it (rigidly: ``−[u_ik]× G_k J_r(θ_k)``, with
``u_ik`` the part of the point that joint ``k`` carries, measured from the joint, see
:mod:`smplcore.fit.body`), on the pose correctives of the joints whose features move it
(``A_i P_ik ∂f_k/∂θ_k``), on the shape coefficients and on the translation. The points are grouped by the
joint that moves them most; a group's Jacobian is dense over its *relevant* joints only — its ancestors
and the joints whose pose correctives move its points noticeably — plus the shape and translation
columns, and its ``Jᵀ W J`` is one small batched product added into the whole matrix. For SMPL-X's
hands, say, a finger's points see a dozen joints of 55, so the matrix costs a fraction of the dense one.

Pose correctives of joints that are not relevant to a group (below 5 % of the group's largest, e.g. a
finger's on the thigh) are left out: the matrix is used for the Gauss–Newton *step* only, while the cost
and the gradient stay exact (:mod:`smplcore.fit.dense`), so the fixed point does not change.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from smplcore.fit import dense
from smplcore.fit.body import FitBody, Points

# A joint's pose correctives are relevant to a group of points when they reach this share of the group's
# largest (per joint: the largest absolute entry over the group's points).
_RELEVANT = 0.05


@dataclass(frozen=True)
class _Group:
    rows: np.ndarray  # (g,) points of the group
    joints: np.ndarray  # (r,) relevant joints: ancestors, then joints with relevant pose correctives
    carried: np.ndarray  # (g, r, m) w_im where influence m of point i is at or below joint r, else 0
    carried_sum: np.ndarray  # (g, r)
    corrective: slice  # the joints with pose correctives in ``joints`` (all but the root)
    posedirs: np.ndarray | None  # (c, 3 g, 9) those joints' pose correctives of the group's points
    columns: np.ndarray  # (3 r + K + 3,) columns of the group's Jacobian in [θ, coeffs, transl]


def _groups(body: FitBody, pts: Points) -> tuple[_Group, ...]:
    """The point set's groups (cached on ``body``)."""
    return body.cached(("normal", pts.ids.tobytes()), lambda: _build_groups(body, pts))


def _relevant_joints(body: FitBody, pts: Points, rows: np.ndarray) -> np.ndarray:
    """The sorted joints relevant to the points ``rows``: their ancestors and the joints whose pose
    correctives move them noticeably."""
    joints = np.unique(pts.ancestors[rows])
    joints = joints[joints < body.num_joints]
    if pts.posedirs is not None:
        size = np.abs(pts.posedirs[rows]).max(axis=(0, 1, 3))  # (J - 1,)
        strong = np.flatnonzero(size >= _RELEVANT * max(size.max(), 1e-300)) + 1
        joints = np.union1d(joints, strong[size[strong - 1] > 0])
    return joints


def _build_groups(body: FitBody, pts: Points) -> tuple[_Group, ...]:
    # a group per main joint, then groups whose relevant joints are a subset of another's are merged into
    # it (a finger's three segments, a wrist into its hand): fewer, larger products
    main = pts.joints[:, 0]
    found = [
        (np.flatnonzero(main == j), _relevant_joints(body, pts, np.flatnonzero(main == j))) for j in np.unique(main)
    ]
    merged: list[tuple[list[np.ndarray], np.ndarray]] = []
    for rows, joints in sorted(found, key=lambda g: -len(g[1])):
        homes = [m for m in merged if np.isin(joints, m[1]).all()]
        if homes:
            min(homes, key=lambda m: len(m[1]))[0].append(rows)
        else:
            merged.append(([rows], joints))
    return tuple(_group(body, pts, np.sort(np.concatenate(rows)), joints) for rows, joints in merged)


def _group(body: FitBody, pts: Points, rows: np.ndarray, joints: np.ndarray) -> _Group:
    tail = 3 * body.num_joints + np.arange(body.num_coeffs + 3)
    carried = body.below_of()[joints[None, :, None], pts.joints[rows][:, None, :]] * pts.weights[rows][:, None, :]
    corrective = slice(int(joints[0] == 0), len(joints))  # sorted: the root comes first
    posedirs = None
    if pts.posedirs is not None and len(joints[corrective]):
        pd = pts.posedirs[rows][:, :, joints[corrective] - 1]  # (g, 3, c, 9)
        posedirs = np.ascontiguousarray(np.moveaxis(pd, 2, 0).reshape(pd.shape[2], 3 * len(rows), 9))
    columns = np.concatenate([(3 * joints[:, None] + np.arange(3)).reshape(-1), tail])
    return _Group(rows, joints, carried, carried.sum(-1), corrective, posedirs, columns)


_WORKSPACE = threading.local()


def _zeroed(shape: tuple[int, ...]) -> np.ndarray:
    """A zeroed float64 array of ``shape``, reusing this thread's last one of that shape: a fresh array of
    tens of megabytes costs a page fault per 4 kB at its first touch, more than the sums written into it."""
    cached = getattr(_WORKSPACE, "array", None)
    if cached is None or cached.shape != shape:
        cached = _WORKSPACE.array = np.zeros(shape)
    else:
        cached.fill(0.0)
    return cached


def _batch_last(a: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """(B, ...) → contiguous (..., B) in ``dtype``."""
    return np.ascontiguousarray(np.moveaxis(a, 0, -1), dtype=dtype)


def normal_matrix(
    body: FitBody,
    pts: Points,
    arrays: dense.DensePoints,
    posed: dense.Posed,
    weights: np.ndarray,
    columns: np.ndarray | None = None,
) -> np.ndarray:
    """(B, P, P) Gauss–Newton matrix over the ``columns`` (default all) of [θ (joint-major axis-angle),
    coeffs, transl] (P = 3 J + K + 3) of the points ``pts`` posed as ``posed`` (:func:`smplcore.fit.dense.pose`
    of ``arrays``) with (B, n) point weights (see the module docstring for what is left out). The Jacobian
    is built batch last (every elementwise product runs over the bodies), in the posed arrays' precision;
    the sum is float64 and contiguous."""
    batch, num_joints = posed.theta.shape[:2]
    k = arrays.num_coeffs
    f = posed.rest.dtype
    root_w = np.sqrt(weights).T.astype(f)  # (n, B)
    world = _batch_last(posed.world, f)  # (J, 3, 3, B)
    shift = _batch_last(posed.shift, f)  # (J, 3, B)
    pos = _batch_last(posed.pos, f)  # (J, 3, B) posed joints
    lift = _batch_last(posed.kin.lift, f)  # (J, 3, 3, B): d world axis / d θ
    blend = posed.blend  # (n, 3, 3, B)
    slopes = None  # (J - 1, 9, 3 B): d f_k / d θ_k of the pose-corrective features
    if arrays.has_pose:
        slopes = _batch_last(posed.kin.slopes, f).reshape(num_joints - 1, 9, 3 * batch)
    coeff_jac = dense.coefficient_jacobian(body, pts, arrays, posed)  # (n, 3, K, B)
    total = 3 * num_joints + k + 3
    position = np.arange(total) if columns is None else np.full(total, -1)
    if columns is not None:
        position[columns] = np.arange(len(columns))
    size_out = total if columns is None else len(columns)
    out = _zeroed((size_out, size_out, batch))  # batch last: each block added is a run of B values
    for g in _groups(body, pts):
        size, r = len(g.rows), len(g.joints)
        # x_im: each point moved by each of its influences alone, then u_ir = Σ_m c_irm x_im − c_ir p_r
        gw = world[pts.joints[g.rows]]  # (g, m, 3, 3, B)
        rest = posed.rest[g.rows][:, None, None]  # (g, 1, 1, 3, B)
        moved = (gw * rest).sum(3) + shift[pts.joints[g.rows]]  # (g, m, 3, B)
        u = np.einsum("iam,imcb->iacb", g.carried.astype(f), moved)  # (g, r, 3, B)
        u -= g.carried_sum.astype(f)[:, :, None, None] * pos[g.joints][None]
        jac = np.zeros((size, 3, 3 * r + k + 3, batch), f)
        rigid = jac[:, :, : 3 * r].reshape(size, 3, r, 3, batch)
        lg = lift[g.joints]  # (r, 3 rows, 3 cols, B)
        u0, u1, u2 = u[:, :, 0, None], u[:, :, 1, None], u[:, :, 2, None]  # (g, r, 1, B)
        rigid[:, 0] = u2 * lg[:, 1] - u1 * lg[:, 2]  # rows of −[u]× L
        rigid[:, 1] = u0 * lg[:, 2] - u2 * lg[:, 0]
        rigid[:, 2] = u1 * lg[:, 0] - u0 * lg[:, 1]
        if g.posedirs is not None and slopes is not None:
            joints = g.joints[g.corrective]
            moves = (g.posedirs.astype(f) @ slopes[joints - 1]).reshape(len(joints), size, 3, 3, batch)
            a = blend[g.rows]  # (g, 3 c, 3 e, B)
            mixed = sum(a[None, :, :, e, None] * moves[:, :, e, None] for e in range(3))  # (c', g, 3 c, 3, B)
            rigid[:, :, g.corrective] += np.moveaxis(mixed, 0, 2)
        jac[:, :, 3 * r : 3 * r + k] = coeff_jac[g.rows]
        jac[:, :, 3 * r + k :] = np.eye(3, dtype=f)[:, :, None]
        jac *= root_w[g.rows, None, None]
        flat = np.ascontiguousarray(np.moveaxis(jac, -1, 0)).reshape(batch, 3 * size, -1)
        gram = np.swapaxes(flat, 1, 2) @ flat
        at = position[g.columns]
        kept = at >= 0
        if not kept.all():
            gram, at = gram[:, kept][:, :, kept], at[kept]
        out[at[:, None], at[None, :]] += np.moveaxis(gram, 0, -1)
    return np.ascontiguousarray(np.moveaxis(out, -1, 0))
