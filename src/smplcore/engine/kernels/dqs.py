"""Dual-quaternion skinning, fast: blended like linear blend skinning, with a sparse sign correction.

:func:`smplcore.engine.reference.dual_quaternion_skinning` puts each joint's dual quaternion ``q_j`` in the
hemisphere of the vertex's most influential joint ``d``: a sign ``s_dj`` per (body, vertex, joint). Here

* every joint's ``q_j`` is first put in the hemisphere of its parent's (level by level down the tree):
  then ``s_dj = +1`` for nearly every pair ``(d, j)`` that shares a vertex (parent and child, siblings),
  and the blend is ``Σ_j w_j q_j``: one product per block of vertices with only the joints that weight it,
  as linear blend skinning's (:mod:`smplcore.engine.kernels.blocked`, the same blocks), 8 rows per body
  instead of 12;
* the pairs ``(d, j)`` whose sign is -1 for some body get ``-2 w_j q_j`` added, from a (P, V) matrix of
  pair weights (pair ``(d, j)`` holds vertex ``v``'s weight of ``j`` when ``v``'s dominant joint is ``d``),
  only in the blocks and body chunks where such a pair occurs (usually none);
* the blended dual quaternions are normalised and applied on (bodies, vertices) planes.

The result equals the reference's up to the overall sign of a vertex's blend, which the transform does
not depend on. Under torch's autograd the same arithmetic runs as plain (recorded) operations.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any

import numpy as np

from smplcore.engine import reference
from smplcore.engine.backend import from_numpy, host_numpy, index, is_torch, namespace
from smplcore.engine.kernels import blocked, gemm
from smplcore.engine.skeleton import KinematicTree, records_gradients


@dataclass(frozen=True)
class Pairs:
    """The (dominant joint, joint) pairs of a set of vertices, in the joint order of the transforms.

    ``dominant`` and ``joint`` are (P,) NumPy index arrays (``dominant_index``, ``joint_index`` the same in
    the weights' namespace); ``weights_t`` the (P, n) pair weights.
    """

    dominant: np.ndarray
    joint: np.ndarray
    weights_t: Any
    dominant_index: Any
    joint_index: Any


def pairs(weights_t: Any, order: tuple[int, ...] | None = None) -> Pairs:
    """The pairs of (J, n) transposed ``weights_t`` (rows in the transforms' order; ``order[i]`` is the
    model joint of row i, so that ties in the dominant joint go to the lowest model index, as in
    :func:`smplcore.engine.reference.dominant_joints`)."""
    w = weights_t.detach().cpu().numpy() if is_torch(weights_t) else np.asarray(weights_t)
    num_joints, num_verts = w.shape
    model_joint = np.arange(num_joints) if order is None else np.asarray(order)  # of each row
    by_model = np.empty_like(w)
    by_model[model_joint] = w
    row_of = np.argsort(model_joint)  # the row of each model joint
    dominant = row_of[by_model.argmax(axis=0)]  # (n,) the row of each vertex's dominant joint
    used = w != 0
    used[dominant, np.arange(num_verts)] = True  # a vertex with all-zero weights still has its pair
    rows, cols = np.nonzero(used)
    pair_of_entry = dominant[cols] * num_joints + rows
    keys, slot = np.unique(pair_of_entry, return_inverse=True)
    pair_w = np.zeros((keys.size, num_verts), dtype=w.dtype)
    pair_w[slot, cols] = w[rows, cols]
    pair_d, pair_j = keys // num_joints, keys % num_joints
    convert = weights_t.new_tensor if is_torch(weights_t) else np.asarray
    return Pairs(pair_d, pair_j, convert(pair_w), index(pair_d, weights_t), index(pair_j, weights_t))


@dataclass(frozen=True)
class PairBlock:
    """The pairs a vertex block uses: ``pairs`` (host) and ``index`` (namespace) into :class:`Pairs`, and their
    (P_b, n) weights over the block's vertices."""

    pairs: np.ndarray
    index: Any
    weights_t: Any


def pair_blocks(pairs_: Pairs, blocks: tuple[blocked.VertexBlock, ...]) -> tuple[PairBlock, ...]:
    """For each vertex block, the pairs of ``pairs_`` that weight any of its vertices."""
    w = pairs_.weights_t
    host = w.detach().cpu().numpy() if is_torch(w) else np.asarray(w)
    out = []
    for b in blocks:
        used = np.flatnonzero((host[:, b.start : b.stop] != 0).any(axis=1))
        idx = index(used, w)
        block_w = w[idx][:, b.start : b.stop]
        out.append(PairBlock(used, idx, block_w.contiguous() if is_torch(block_w) else np.ascontiguousarray(block_w)))
    return tuple(out)


def joint_dual_quaternions(transforms: Any, tree: KinematicTree) -> Any:
    """(B, J, 8) dual quaternions of (B, J, 12) skinning transforms (depth order), each in the hemisphere
    of its parent's."""
    xp = namespace(transforms)
    batch, num_joints = transforms.shape[:2]
    dq = reference.dual_quaternions(transforms[..., :9].reshape(batch, num_joints, 3, 3), transforms[..., 9:])
    start, stop = tree.level_bounds[0]
    levels = [dq[:, start:stop]]
    for (start, stop), slots in zip(tree.level_bounds[1:], tree.indices(dq)["slots"]):
        q = dq[:, start:stop]
        parent = levels[-1][:, slots]
        levels.append(xp.where((q[..., :4] * parent[..., :4]).sum(axis=-1, keepdims=True) < 0, -q, q))
    return xp.concat(levels, axis=1)


def _prepare(transforms: Any, tree: KinematicTree, pairs_: Pairs) -> tuple[Any, Any, np.ndarray | None]:
    """The joint rows (J, B·8), the correction rows (P, B·8) (or None) and the host (B, P) mask of the
    pairs whose sign is -1 (or None when there is none)."""
    host = host_numpy(transforms) if is_torch(transforms) else None  # a small batch: per-joint math in NumPy
    if host is None:
        args = (transforms, pairs_.dominant_index, pairs_.joint_index)
    else:
        args = (host, pairs_.dominant, pairs_.joint)
    dq = joint_dual_quaternions(args[0], tree)
    joint = dq[:, args[2]]
    flipped = (dq[:, args[1], :4] * joint[..., :4]).sum(axis=-1) < 0  # (B, P)
    mask = flipped.detach().cpu().numpy() if is_torch(flipped) else np.asarray(flipped)
    correction = None
    if mask.any():
        xp = namespace(dq)
        keep = xp.where(flipped[..., None], xp.ones_like(joint[..., :1]), xp.zeros_like(joint[..., :1]))
        correction = _rows(-2 * joint * keep)
    rows = _rows(dq)
    if host is not None:
        rows = from_numpy(np.ascontiguousarray(rows))
        correction = None if correction is None else from_numpy(np.ascontiguousarray(correction))
    return rows, correction, (mask if mask.any() else None)


def _rows(x: Any) -> Any:
    """(B, K, 8) → (K, B·8)."""
    t = x.permute(1, 0, 2) if is_torch(x) else x.transpose(1, 0, 2)
    return t.reshape(t.shape[0], -1)


def skin(
    rest: Any,
    transforms: Any,
    blocks: tuple[blocked.VertexBlock, ...],
    pblocks: tuple[PairBlock, ...],
    pairs_: Pairs,
    tree: KinematicTree,
    feats: Any = None,
) -> Any:
    """(B, V, 3) posed vertices by dual-quaternion skinning.

    Parameters
    ----------
    rest : (B, 3, V) rest-pose vertices (shaped, with pose correctives), one row per coordinate; or None
        when ``feats`` and every block's ``packed_blend`` give them block by block.
    transforms : (B, J, 12) skinning transforms in depth order (the rows of the blocks' weights).
    blocks : vertex blocks of the transposed skinning weights (:func:`blocked.vertex_blocks`).
    pblocks : :func:`pair_blocks` of ``pairs_`` and ``blocks``; pairs_ : :func:`pairs` of the weights.
    tree : the kinematic tree.
    feats : (B, R) blend features, for ``rest=None``.
    """
    rows, correction, flipped = _prepare(transforms, tree, pairs_)
    if records_gradients(rest, rows):
        return _skin_recorded(rest, rows, correction, flipped, blocks, pblocks)
    batch = transforms.shape[0]
    num_verts = blocks[-1].stop
    size = max(b.stop - b.start for b in blocks)
    sub = min(batch, max(1, _APPLY_VALUES // size))  # bodies per step
    out = blocked.empty((batch, num_verts, 3), transforms)
    blend_buf = None if all(b.packed_weights is not None for b in blocks) else blocked.empty((8 * sub * size,), out)
    work = blocked.empty((8 * sub * size,), out)  # work planes of _apply_into
    for block, pblock in zip(blocks, pblocks):
        n = block.stop - block.start
        if rest is None:
            block_rest = gemm.product(feats, block.packed_blend).view(batch, 3, n)
        else:
            block_rest = rest[:, :, block.start : block.stop]
        block_rows = blocked.block_rows(rows, block).T  # (B·8, J_b)
        fix = None if flipped is None else correction[pblock.index].T  # (B·8, P_b)
        for b0 in range(0, batch, sub):
            b1 = min(batch, b0 + sub)
            m = b1 - b0
            chunk_rows = block_rows[8 * b0 : 8 * b1]
            if block.packed_weights is not None:
                q = gemm.product(chunk_rows, block.packed_weights)
            else:
                assert blend_buf is not None  # allocated where some weights are not packed
                q = blocked._matmul(chunk_rows, block.weights_t, blend_buf[: 8 * m * n].reshape(8 * m, n))
            if fix is not None and flipped is not None and flipped[b0:b1, pblock.pairs].any():
                q = q + fix[8 * b0 : 8 * b1] @ pblock.weights_t
            _apply_into(q.reshape(m, 8, n), block_rest[b0:b1], out[b0:b1, block.start : block.stop], work)
    return out


# Values per (bodies × block) plane while skinning (as in the blocked kernel).
_APPLY_VALUES = 1 << 17


def _skin_recorded(rest, rows, correction, flipped, blocks, pblocks) -> Any:
    """:func:`skin` by plain (autograd-recorded) operations."""
    xp = namespace(rest)
    batch = rest.shape[0]
    out = []
    for block, pblock in zip(blocks, pblocks):
        n = block.stop - block.start
        q = blocked.block_rows(rows, block).T @ block.weights_t
        if flipped is not None and flipped[:, pblock.pairs].any():
            q = q + correction[pblock.index].T @ pblock.weights_t
        out.append(_apply(q.reshape(batch, 8, n), rest[:, :, block.start : block.stop]))
    moved = out[0] if len(out) == 1 else xp.concat(out, axis=2)  # (B, 3, V)
    return moved.mT


def _apply(q: Any, v: Any) -> Any:
    """(B, 3, n) rest vertices ``v`` moved by the (B, 8, n) blended dual quaternions ``q``:
    :func:`smplcore.engine.reference.apply_dual_quaternions` with the coordinates first, and its two cross
    products with ``r`` merged: ``v + 2 / |q|² (r × (r × v + w v + rₑ) + w rₑ - wₑ r)``."""
    w, r, we, re = q[:, :1], q[:, 1:4], q[:, 4:5], q[:, 5:8]
    moved = _cross(r, _cross(r, v) + w * v + re) + w * re - we * r
    return v + (2 / (q[:, :4] * q[:, :4]).sum(axis=1, keepdims=True)) * moved


def _cross(a: Any, b: Any) -> Any:
    """Cross products along axis 1 of (m, 3, n) arrays (written out: torch's linalg.cross is slow here)."""
    xp = namespace(a)
    ax, ay, az = a[:, 0], a[:, 1], a[:, 2]
    bx, by, bz = b[:, 0], b[:, 1], b[:, 2]
    return xp.stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx], axis=1)


def _apply_into(q: Any, v: Any, target: Any, work: Any) -> None:
    """:func:`_apply` written into ``target`` (m, n, 3), plane by plane (fused multiply-adds in torch), with
    ``work`` holding at least 8 (m, n) planes."""
    m, _, n = q.shape
    w, rx, ry, rz, we, ex, ey, ez = (q[:, i] for i in range(8))
    vx, vy, vz = v[:, 0], v[:, 1], v[:, 2]
    ix, iy, iz, mx, my, mz, scale, scratch = (work[i * m * n : (i + 1) * m * n].reshape(m, n) for i in range(8))
    cyclic = ((0, 1, 2), (1, 2, 0), (2, 0, 1))  # (c, a, b): (r × u)_c = r_a u_b - r_b u_a
    r, e, vs, inner, moved = (rx, ry, rz), (ex, ey, ez), (vx, vy, vz), (ix, iy, iz), (mx, my, mz)
    for c, a, b in cyclic:  # inner = r × v + w v + rₑ
        _mul(w, vs[c], inner[c])
        _add(inner[c], e[c])
        _fma(inner[c], r[a], vs[b], 1, scratch)
        _fma(inner[c], r[b], vs[a], -1, scratch)
    for c, a, b in cyclic:  # moved = r × inner + w rₑ - wₑ r
        _mul(w, e[c], moved[c])
        _fma(moved[c], we, r[c], -1, scratch)
        _fma(moved[c], r[a], inner[b], 1, scratch)
        _fma(moved[c], r[b], inner[a], -1, scratch)
    _mul(w, w, scale)
    for rc in r:
        _fma(scale, rc, rc, 1, scratch)
    if is_torch(scale):
        scale.reciprocal_().mul_(2)
        for c in range(3):
            sys.modules["torch"].addcmul(vs[c], scale, moved[c], out=target[..., c])
    else:
        np.divide(2, scale, out=scale)
        for c in range(3):
            np.multiply(scale, moved[c], out=scratch)
            np.add(vs[c], scratch, out=target[..., c])


def _mul(a: Any, b: Any, out: Any) -> None:
    if is_torch(a):
        sys.modules["torch"].mul(a, b, out=out)
    else:
        np.multiply(a, b, out=out)


def _add(acc: Any, a: Any) -> None:
    if is_torch(acc):
        acc.add_(a)
    else:
        np.add(acc, a, out=acc)


def _fma(acc: Any, a: Any, b: Any, sign: int, scratch: Any) -> None:
    """``acc += sign * a * b`` in place."""
    if is_torch(acc):
        acc.addcmul_(a, b, value=sign)
    else:
        np.multiply(a, b, out=scratch)
        (np.add if sign > 0 else np.subtract)(acc, scratch, out=acc)
