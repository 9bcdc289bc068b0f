"""Dual-quaternion skinning, fast: blended like linear blend skinning, with a sparse sign correction.

:func:`smplcore.engine.reference.dual_quaternion_skinning` puts each joint's dual quaternion ``q_j`` in the
hemisphere of the vertex's most influential joint ``d``: a sign ``s_dj`` per (body, vertex, joint). Here

* every joint's ``q_j`` is first put in the hemisphere of its parent's (a joint's sign flips once per joint
  on its path from the root that points away from its parent: one product with the tree's ancestor matrix):
  then ``s_dj = +1`` for nearly every pair ``(d, j)`` that shares a vertex (parent and child, siblings),
  and the blend is ``Σ_j w_j q_j``: one product per block of vertices with only the joints that weight it,
  as linear blend skinning's (:mod:`smplcore.engine.kernels.blocked`, the same blocks), 10 rows per body
  (:data:`LAYOUT`: the 8 values, two of them twice) instead of 12;
* the pairs ``(d, j)`` whose sign is -1 for some body get ``-2 w_j q_j`` added, from a (P, V) matrix of
  pair weights (pair ``(d, j)`` holds vertex ``v``'s weight of ``j`` when ``v``'s dominant joint is ``d``),
  only in the blocks and body chunks where such a pair occurs (usually none);
* the blended dual quaternions (a (10, bodies, vertices) stack of planes: the rows list one value for every
  body, :func:`_rows`) are normalised and applied to the block's rest vertices (computed block by block into
  reused planes, :func:`_rest_planes`) by 12-20 operations on three planes at a time (:func:`_apply_into`);
  for a few bodies in torch, by NumPy on the tensors' memory (:data:`_TORCH_MIN_PLANE`).

The result equals the reference's up to the overall sign of a vertex's blend, which the transform does
not depend on. Under torch's autograd the same arithmetic runs as plain (recorded) operations.
"""

from __future__ import annotations

import functools
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


# The 10 values per joint (and per blended vertex) of a dual quaternion (w, x, y, z, wₑ, xₑ, yₑ, zₑ) that the
# blend product carries, in this order: x y z x y w wₑ xₑ yₑ zₑ. Rows 0:3 are r = (x, y, z); rows 1:4 and 2:5
# the same cyclically shifted (r_a and r_b of the cross products (r × u)_c = r_a u_b - r_b u_a), so that each
# step of the transform is one operation on three planes; rows 2:6 hold the four values of the rotation
# quaternion (for its norm); row 6 is wₑ and rows 7:10 are rₑ.
LAYOUT = (1, 2, 3, 1, 2, 0, 4, 5, 6, 7)
ROWS = len(LAYOUT)


def _quaternion_constants() -> tuple[np.ndarray, np.ndarray]:
    """(10, 16) ``S`` and (12, 4) ``D``: for a rotation R and translation t, ``[1, R00, R01, ..., R22] @ S`` is
    ``4 q qᵀ`` (row-major) of R's quaternion ``q = (w, x, y, z)`` (Shepperd's table: its diagonal is
    ``1 ± R00 ± R11 ± R22``, the rest sums and differences of opposite entries), and ``vec(t qᵀ) @ D`` is the
    dual part ``½ (0, t) q``."""
    s = np.zeros((10, 4, 4))
    s[0] = np.eye(4)
    for k, signs in enumerate(((1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1))):
        for i in range(3):
            s[1 + 4 * i, k, k] = signs[i]
    # 4 w x = R21 - R12, 4 w y = R02 - R20, 4 w z = R10 - R01, 4 x y = R01 + R10, 4 x z = R02 + R20, 4 y z = R12 + R21
    for (a, b), (i, j), sign in (
        ((0, 1), (2, 1), 1), ((0, 1), (1, 2), -1), ((0, 2), (0, 2), 1), ((0, 2), (2, 0), -1),
        ((0, 3), (1, 0), 1), ((0, 3), (0, 1), -1), ((1, 2), (0, 1), 1), ((1, 2), (1, 0), 1),
        ((1, 3), (0, 2), 1), ((1, 3), (2, 0), 1), ((2, 3), (1, 2), 1), ((2, 3), (2, 1), 1),
    ):  # fmt: skip
        s[1 + 3 * i + j, a, b] = s[1 + 3 * i + j, b, a] = sign
    basis = np.eye(4)
    d = np.stack([0.5 * reference.quaternion_product(basis[1 + i], basis[j]) for i in range(3) for j in range(4)])
    return s.reshape(10, 16), d


_SHEPPERD, _DUAL = _quaternion_constants()


def _constant(matrix: np.ndarray, like: Any) -> Any:
    """``matrix`` in the namespace, dtype (and device) of ``like``."""
    return like.new_tensor(matrix) if is_torch(like) else matrix.astype(like.dtype, copy=False)


def dual_quaternions(transforms: Any) -> Any:
    """(B, J, 8) unit dual quaternions of (B, J, 12) skinning transforms: the same as
    :func:`smplcore.engine.reference.dual_quaternions` (the same branch of Shepperd's method, so the same
    sign) in a few whole-array operations."""
    xp = namespace(transforms)
    batch, num_joints = transforms.shape[:2]
    s = _constant(_SHEPPERD, transforms)
    outer = (transforms[..., :9] @ s[1:] + s[0]).reshape(batch, num_joints, 4, 4)  # 4 q qᵀ
    diagonal = outer.reshape(batch, num_joints, 16)[..., ::5]  # 4 w², 4 x², 4 y², 4 z²
    best = diagonal.argmax(axis=-1)[..., None]  # the largest: at least 1
    take = sys.modules["torch"].take_along_dim if is_torch(transforms) else np.take_along_axis
    real = take(outer, best[..., None], -2)[..., 0, :] / (2 * xp.sqrt(take(diagonal, best, -1)))  # 4 s q / 4 s
    t_q = (transforms[..., 9:, None] * real[..., None, :]).reshape(batch, num_joints, 12)
    return xp.concat([real, t_q @ _constant(_DUAL, transforms)], axis=-1)


@functools.lru_cache(maxsize=16)
def _ancestors(parents: tuple[int, ...], order: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """For the joints in depth ``order``: the (J,) row of each one's parent (the root's: itself) and the (J, J)
    matrix whose row i marks row i and its ancestors below the root."""
    row_of = {joint: i for i, joint in enumerate(order)}
    parent_rows = np.array([row_of[max(parents[joint], 0)] for joint in order])
    ancestors = np.zeros((len(order), len(order)))
    for i in range(1, len(order)):
        ancestors[i] = ancestors[parent_rows[i]]
        ancestors[i, i] = 1
    return parent_rows, ancestors


def joint_dual_quaternions(transforms: Any, tree: KinematicTree) -> Any:
    """(B, J, 8) dual quaternions of (B, J, 12) skinning transforms (depth order), each in the hemisphere
    of its parent's: a joint's sign flips once per joint on its path from the root (itself included) whose
    quaternion points away from its parent's."""
    xp = namespace(transforms)
    dq = dual_quaternions(transforms)
    parent_rows, ancestors = _ancestors(tree.parents, tree.order)
    real = dq[..., :4]
    away = (real * real[:, index(parent_rows, dq)]).sum(axis=-1) < 0  # (B, J)
    one = xp.ones_like(dq[..., 0])
    flips = xp.where(away, one, 0 * one) @ _constant(ancestors.T, dq)  # (B, J) flips along the path
    return dq * (1 - 2 * (flips % 2))[..., None]


def _prepare(transforms: Any, tree: KinematicTree, pairs_: Pairs) -> tuple[Any, Any, np.ndarray | None]:
    """The joint rows (J, 10·B) (:func:`_rows`), the correction rows (P, 10·B) (or None) and the host (B, P)
    mask of the pairs whose sign is -1 (or None when there is none)."""
    host = host_numpy(transforms) if is_torch(transforms) else None  # a small batch: per-joint math in NumPy
    if host is None:
        args = (transforms, pairs_.dominant_index, pairs_.joint_index)
    else:
        args = (host, pairs_.dominant, pairs_.joint)
    dq = joint_dual_quaternions(args[0], tree)
    layout = index(LAYOUT, dq)
    flipped = (dq[:, args[1], :4] * dq[:, args[2], :4]).sum(axis=-1) < 0  # (B, P)
    mask = flipped.detach().cpu().numpy() if is_torch(flipped) else np.asarray(flipped)
    correction = None
    if mask.any():
        joint = dq[:, args[2]][..., layout]
        correction = _rows(namespace(dq).where(flipped[..., None], -2 * joint, 0 * joint))
    rows = _rows(dq[..., layout])
    if host is not None:
        rows = from_numpy(np.ascontiguousarray(rows))
        correction = None if correction is None else from_numpy(np.ascontiguousarray(correction))
    return rows, correction, (mask if mask.any() else None)


def _rows(x: Any) -> Any:
    """(B, K, 10) → (K, 10·B): per row, the values of :data:`LAYOUT` one after the other, each for every body
    (column ``k·B + b``), so that a product gives (10, bodies, vertices) planes."""
    t = x.permute(1, 2, 0) if is_torch(x) else x.transpose(1, 2, 0)
    return t.reshape(t.shape[0], -1)


def _chunk(rows: Any, b0: int, b1: int) -> Any:
    """(10·m, K): the columns of bodies ``b0:b1`` of (K, 10·B) :func:`_rows`, as rows of a product's left side."""
    k = rows.shape[0]
    t = rows.reshape(k, ROWS, -1)[:, :, b0:b1]
    t = t.permute(1, 2, 0) if is_torch(t) else t.transpose(1, 2, 0)
    return t.reshape(-1, k)


def skin(
    rest: Any,
    transforms: Any,
    blocks: tuple[blocked.VertexBlock, ...],
    pblocks: tuple[PairBlock, ...],
    pairs_: Pairs,
    tree: KinematicTree,
    feats: Any = None,
    basis: Any = None,
) -> Any:
    """(B, V, 3) posed vertices by dual-quaternion skinning.

    Parameters
    ----------
    rest : (B, 3, V) rest-pose vertices (shaped, with pose correctives), one row per coordinate; or None
        when ``feats @ basis`` gives them block by block (:func:`_rest_planes`).
    transforms : (B, J, 12) skinning transforms in depth order (the rows of the blocks' weights).
    blocks : vertex blocks of the transposed skinning weights (:func:`blocked.vertex_blocks`).
    pblocks : :func:`pair_blocks` of ``pairs_`` and ``blocks``; pairs_ : :func:`pairs` of the weights.
    tree : the kinematic tree.
    feats : (B, R) blend features and basis : (≥ R, 3 V) coordinate-major blend basis, for ``rest=None``.
    """
    rows, correction, flipped = _prepare(transforms, tree, pairs_)
    if records_gradients(rest, rows):
        return _skin_recorded(rest, rows, correction, flipped, blocks, pblocks)
    batch = transforms.shape[0]
    num_verts = blocks[-1].stop
    size = max(b.stop - b.start for b in blocks)
    sub = min(batch, max(1, _APPLY_VALUES[is_torch(transforms)] // size))  # bodies per step
    out = blocked.empty((batch, num_verts, 3), transforms)
    blend_buf = None if all(b.packed_weights is not None for b in blocks) else blocked.empty((ROWS * sub * size,), out)
    work = blocked.empty((_WORK_PLANES * sub * size,), out)  # work planes of _apply_into
    rest_buf = blocked.empty((5 * batch * size,), out)
    for block, pblock in zip(blocks, pblocks):
        n = block.stop - block.start
        v5 = _rest_planes(rest_buf[: 5 * batch * n].reshape(5, batch, n), block, rest, feats, basis)
        block_rows = blocked.block_rows(rows, block)  # (J_b, 10·B)
        fix = None if flipped is None else correction[pblock.index]  # (P_b, 10·B)
        for b0 in range(0, batch, sub):
            b1 = min(batch, b0 + sub)
            m = b1 - b0
            chunk_rows = _chunk(block_rows, b0, b1)
            if block.packed_weights is not None:
                q = gemm.product(chunk_rows, block.packed_weights)
            else:
                assert blend_buf is not None  # allocated where some weights are not packed
                q = blocked._matmul(chunk_rows, block.weights_t, blend_buf[: ROWS * m * n].reshape(ROWS * m, n))
            if fix is not None and flipped is not None and flipped[b0:b1, pblock.pairs].any():
                q = q + _chunk(fix, b0, b1) @ pblock.weights_t
            args = (q.reshape(ROWS, m, n), v5[:, b0:b1], out[b0:b1, block.start : block.stop], work)
            if is_torch(q) and m * n < _TORCH_MIN_PLANE:  # a few bodies: NumPy on the same memory is faster
                args = tuple(a.numpy() for a in args)
            _apply_into(*args)
    return out


def _rest_planes(v5: Any, block: blocked.VertexBlock, rest: Any, feats: Any, basis: Any) -> Any:
    """``v5`` (5, B, n) filled with the rest vertices of ``block``: planes x, y, z, x, y (for the cross
    products of :func:`_apply_into`), from ``rest`` or from ``feats @ basis``: the block's packed basis
    columns, one product for a lone block (three strided ones are slow for a few bodies), else one per
    coordinate straight into its plane (a mesh-sized rest array would cost its page faults at every call)."""
    batch, n = v5.shape[1:]
    if rest is None:
        num_rows, num_verts = feats.shape[1], basis.shape[1] // 3
        if block.packed_blend is not None and num_rows == basis.shape[0]:
            rest = gemm.product(feats, block.packed_blend).view(batch, 3, n)
        elif n == num_verts:
            rest = (feats @ basis[:num_rows]).reshape(batch, 3, n)  # (a few bodies: small)
        else:
            for c in range(3):
                start = c * num_verts + block.start
                blocked._matmul(feats, basis[:num_rows, start : start + n], v5[c])
    else:
        rest = rest[:, :, block.start : block.stop]
    if rest is not None:
        _copy(v5[:3], rest.transpose(0, 1) if is_torch(rest) else rest.transpose(1, 0, 2))
    _copy(v5[3:], v5[:2])
    return v5


def _copy(target: Any, source: Any) -> None:
    """``target[...] = source``; torch tensors of a few bodies through NumPy (see :data:`_TORCH_MIN_PLANE`)."""
    if is_torch(target) and target[0].numel() >= _TORCH_MIN_PLANE:  # (k, B, n): planes of B n values
        target.copy_(source)
    else:
        np.copyto(*(a.numpy() if is_torch(a) else a for a in (target, source)))


# Values per (bodies × block) plane while skinning, NumPy and torch: the blend (10 planes), the work planes
# (13) and the rest vertices (5) of a step stay in cache; torch, whose operations have more overhead and run on
# all its threads, takes twice as many (measured on SMPL and the open model at B = 512).
_APPLY_VALUES = (1 << 15, 1 << 16)
_WORK_PLANES = 13
# Below this many values per plane (B = 1 and a few bodies), torch's per-operation overhead (and its threads,
# which it starts on operations over 32768 values) costs more than the arithmetic: the transform then runs
# NumPy's operations on the tensors' memory.
_TORCH_MIN_PLANE = 1 << 15


def _skin_recorded(rest, rows, correction, flipped, blocks, pblocks) -> Any:
    """:func:`skin` by plain (autograd-recorded) operations."""
    xp = namespace(rest)
    batch = rest.shape[0]
    out = []
    for block, pblock in zip(blocks, pblocks):
        n = block.stop - block.start
        q = _chunk(blocked.block_rows(rows, block), 0, batch) @ block.weights_t
        if flipped is not None and flipped[:, pblock.pairs].any():
            q = q + _chunk(correction[pblock.index], 0, batch) @ pblock.weights_t
        out.append(_apply(q.reshape(ROWS, batch, n), rest[:, :, block.start : block.stop].swapaxes(0, 1)))
    moved = out[0] if len(out) == 1 else xp.concat(out, axis=2)  # (3, B, V)
    return xp.moveaxis(moved, 0, -1)


def _apply(q: Any, v: Any) -> Any:
    """(3, B, n) rest vertices ``v`` moved by the (10, B, n) blended dual quaternions ``q`` (:data:`LAYOUT`):
    :func:`smplcore.engine.reference.apply_dual_quaternions` with the coordinates first, and its two cross
    products with ``r`` merged: ``v + 2 / |q|² (r × (r × v + w v + rₑ) + w rₑ - wₑ r)``."""
    r, w, we, re = q[0:3], q[5:6], q[6:7], q[7:10]
    moved = _cross(r, _cross(r, v) + w * v + re) + w * re - we * r
    return v + (2 / (q[2:6] * q[2:6]).sum(axis=0, keepdims=True)) * moved


def _cross(a: Any, b: Any) -> Any:
    """Cross products along axis 0 of (3, ...) arrays (written out: torch's linalg.cross is slow here)."""
    xp = namespace(a)
    ax, ay, az = a[0], a[1], a[2]
    bx, by, bz = b[0], b[1], b[2]
    return xp.stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx], axis=0)


def _apply_into(q: Any, v5: Any, target: Any, work: Any) -> None:
    """:func:`_apply` written into ``target`` (m, n, 3) for (10, m, n) ``q`` and the (5, m, n) rest vertices
    ``v5`` (x, y, z, x, y: :func:`_rest_planes`), with ``work`` holding :data:`_WORK_PLANES` (m, n) planes: each
    step one operation on three planes. A cross product ``r × u`` is ``r_a u_b - r_b u_a`` over the three
    components at once, with ``r_a, r_b`` rows 1:4 and 2:5 of ``q`` and ``u`` in (x, y, z, x, y) planes."""
    _, m, n = q.shape
    planes = work[: _WORK_PLANES * m * n].reshape(_WORK_PLANES, m, n)
    r, r_a, r_b, w, we, e = q[0:3], q[1:4], q[2:5], q[5:6], q[6:7], q[7:10]
    inner5, moved, tmp, scale = planes[0:5], planes[5:8], planes[8:12], planes[12]
    v3, inner, tmp3 = v5[:3], inner5[:3], tmp[:3]
    if is_torch(q):
        torch = sys.modules["torch"]
        torch.addcmul(e, w, v3, out=inner)  # inner = r × v + w v + rₑ
        inner.addcmul_(r_a, v5[2:5]).addcmul_(r_b, v5[1:4], value=-1)
        inner5[3:].copy_(inner[:2])
        torch.mul(w, e, out=moved)  # moved = r × inner + w rₑ - wₑ r
        moved.addcmul_(we, r, value=-1).addcmul_(r_a, inner5[2:5]).addcmul_(r_b, inner5[1:4], value=-1)
        torch.mul(w[0], w[0], out=scale)  # |q|², plane by plane (faster than a sum over the rows)
        for c in range(3):
            scale.addcmul_(r[c], r[c])
        scale.reciprocal_().mul_(2)
        target.copy_(torch.addcmul(v3, scale, moved, out=moved).permute(1, 2, 0))  # (a strided write is slower)
        return
    np.multiply(r_a, v5[2:5], out=inner)
    np.multiply(r_b, v5[1:4], out=tmp3)
    inner -= tmp3
    np.multiply(w, v3, out=tmp3)
    inner += tmp3
    inner += e
    np.copyto(inner5[3:], inner[:2])
    np.multiply(r_a, inner5[2:5], out=moved)
    np.multiply(r_b, inner5[1:4], out=tmp3)
    moved -= tmp3
    np.multiply(w, e, out=tmp3)
    moved += tmp3
    np.multiply(we, r, out=tmp3)
    moved -= tmp3
    np.multiply(q[2:6], q[2:6], out=tmp)  # |q|²: added plane by plane (faster than np.sum over the rows)
    np.add(tmp[0], tmp[1], out=scale)
    scale += tmp[2]
    scale += tmp[3]
    np.divide(2, scale, out=scale)
    moved *= scale
    np.add(v3, moved, out=target.transpose(2, 0, 1))
