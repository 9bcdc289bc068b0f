"""Inference fast path: blend shapes and skinning fused over blocks of vertices.

The plain pass (:func:`~smplcore.engine.body.rest_vertices` then :func:`~smplcore.engine.skeleton.skin`)
builds the whole (B, 3, V) rest mesh and the blended per-vertex transforms before skinning, and streams
them through memory. Here the mesh is cut into blocks of vertices and, for the whole batch at once,
each block is blended, skinned and written to the output while its values are still in cache:

* rest-pose block: ``[1, coeffs, pose features] @ blend_basis[:, block]``, one GEMM per coordinate;
* blended 3×4 transforms: ``transforms @ weights_t[joints, block]`` over only the joints that weight
  any vertex of the block (a vertex has 1–4; a block of neighbouring vertices a handful);
* the transforms applied with three fused multiply-adds per output coordinate.

Same arithmetic as the plain pass (the dropped weights are exact zeros); no autograd graph is kept,
so callers use it only when no gradient is recorded.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import Any

import numpy as np

from smplcore.engine.backend import index, is_torch
from smplcore.engine.kernels import gemm

# Values per (B × block) plane: blocks are sized so one block's temporaries (15 planes) stay in
# the last-level cache. 2**19 measured best for SMPL and SMPL-X at B = 512 (bench/profile_forward.py).
_PLANE_VALUES = 1 << 19
_MIN_BLOCK = 256
# Values per (bodies × block) plane while skinning: the blended transforms of 128 bodies × 1024
# vertices (6 MB) instead of the whole batch's.
_APPLY_VALUES = 1 << 17


@dataclass(frozen=True)
class VertexBlock:
    """Vertices ``start:stop``, the joints that weight any of them, and those weights (J_b, n).

    Where :mod:`~smplcore.engine.gemm` packs matrices, ``packed_weights`` is ``weights_t`` packed (for
    ``transforms @ weights_t``), ``packed_weights_t`` its transpose (for the skinning backward) and
    ``packed_blend`` the block's columns of the blend basis (x, y, z of its vertices).
    """

    start: int
    stop: int
    joints: Any  # index array, or None for all joints
    weights_t: Any
    packed_weights: Any = None
    packed_weights_t: Any = None
    packed_blend: Any = None


def vertex_columns(ids: np.ndarray, num_verts: int) -> np.ndarray:
    """Columns of a coordinate-major ``blend_basis`` holding vertices ``ids`` (x of all, then y, then z)."""
    return (np.arange(3)[:, None] * num_verts + np.asarray(ids)[None]).reshape(-1)


def vertex_blocks(weights_t: Any, size: int, blend_basis: Any = None) -> tuple[VertexBlock, ...]:
    """Cut (J, V) transposed skinning weights (and the (R, 3 V) ``blend_basis``, when given and
    packable) into blocks of ``size`` vertices."""
    num_joints, num_verts = weights_t.shape
    used_by = np.asarray(_to_numpy(weights_t) != 0)
    pack_blend = blend_basis is not None and gemm.available(blend_basis)
    blocks = []
    for start in range(0, num_verts, size):
        stop = min(start + size, num_verts)
        joints = np.flatnonzero(used_by[:, start:stop].any(axis=1))
        if joints.size == num_joints:
            idx, block_weights = None, weights_t[:, start:stop]
        else:
            idx = index(joints, weights_t)
            block_weights = _contiguous(weights_t[idx][:, start:stop])
        packed_blend = None
        if pack_blend:
            cols = index(vertex_columns(np.arange(start, stop), num_verts), blend_basis)
            packed_blend = gemm.pack(blend_basis[:, cols])
        blocks.append(
            VertexBlock(
                start, stop, idx, block_weights, gemm.pack(block_weights), gemm.pack(block_weights.T), packed_blend
            )
        )
    return tuple(blocks)


def block_size(batch: int, num_verts: int) -> int:
    """Vertices per block for a batch: the whole mesh for small batches, else ~2**19 values per plane."""
    size = max(_MIN_BLOCK, _PLANE_VALUES // max(batch, 1))
    return num_verts if size >= num_verts else 1 << (size.bit_length() - 1)


def posed_vertices(feats: Any, transforms: Any, blend_basis: Any, blocks: tuple[VertexBlock, ...]) -> Any:
    """(B, V, 3) skinned vertices, without building the rest-pose mesh.

    Parameters
    ----------
    feats : (B, R) ``[1, coeffs, pose features]``; ``blend_basis`` rows beyond R are not used.
    transforms : (B, J, 12) skinning transforms (translation folded in).
    blend_basis : (≥ R, 3 V) coordinate-major basis (see :class:`~smplcore.engine.body.BodyArrays`).
    blocks : from :func:`vertex_blocks`, covering the V vertices in order.
    """
    batch, num_rows = feats.shape
    num_verts = blocks[-1].stop
    size = max(b.stop - b.start for b in blocks)
    basis = blend_basis[:num_rows]
    # (J, B·12): one row per joint, R00 R01 ... R22 tx ty tz of each body; a block gathers its rows
    # (a lone block, e.g. the few vertices of the keypoints, takes just its joints' transforms)
    per_joint = None if len(blocks) == 1 else per_joint_rows(transforms)
    out = empty((batch, num_verts, 3), feats)
    sub = min(batch, max(1, _APPLY_VALUES // size))  # bodies per skinning step
    packed_blend = num_rows == blend_basis.shape[0] and all(b.packed_blend is not None for b in blocks)
    rest_buf: Any = None if packed_blend else empty((3 * batch * size,), feats)
    blend_buf = None if all(b.packed_weights is not None for b in blocks) else empty((12 * sub * size,), feats)
    tmp_buf = empty((sub * size,), feats)
    scratch_buf = None if is_torch(feats) else empty((sub * size,), feats)  # NumPy has no fused multiply-add
    for block in blocks:
        start, stop, n = block.start, block.stop, block.stop - block.start
        if packed_blend:
            rest = gemm.product(feats, block.packed_blend).view(batch, 3, n).transpose(0, 1)
        elif n == num_verts:  # one block: one product (three strided ones are slow for a few bodies)
            rest = _matmul(feats, basis, rest_buf[: 3 * batch * n].reshape(batch, 3 * n)).reshape(batch, 3, n)
            rest = rest.transpose(0, 1) if is_torch(rest) else rest.transpose(1, 0, 2)
        else:
            rest = rest_buf[: 3 * batch * n].reshape(3, batch, n)
            for c in range(3):
                _matmul(feats, basis[:, c * num_verts + start : c * num_verts + stop], rest[c])
        joint_rows = (per_joint_rows(transforms, block.joints) if per_joint is None else block_rows(per_joint, block)).T
        for b0 in range(0, batch, sub):
            b1 = min(batch, b0 + sub)
            m = b1 - b0
            g = blended_transforms(joint_rows[12 * b0 : 12 * b1], block, blend_buf, m * n).reshape(m, 12, n)
            tmp = tmp_buf[: m * n].reshape(m, n)
            scratch = None if scratch_buf is None else scratch_buf[: m * n].reshape(m, n)
            apply_blended(g, rest[:, b0:b1], out[b0:b1, start:stop], tmp, scratch)
    return out


def blended_transforms(rows: Any, block: VertexBlock, buffer: Any, values: int) -> Any:
    """(12 m, n) ``rows @ block.weights_t``: per-vertex blended transforms of m bodies from the (12 m, J_b)
    rows of their transforms (a new array when packed, else the first 12 ``values`` of ``buffer``)."""
    if block.packed_weights is not None:
        return gemm.product(rows, block.packed_weights)
    return _matmul(rows, block.weights_t, buffer[: 12 * values].reshape(rows.shape[0], -1))


def apply_blended(g: Any, rest: Any, target: Any, tmp: Any, scratch: Any = None) -> None:
    """``target`` (m, n, 3) = per-vertex 3×4 transforms ``g`` (m, 12, n) applied to ``rest`` (3, m, n).

    ``tmp`` is an (m, n) work plane; ``scratch`` another, for NumPy only.
    """
    x, y, z = rest[0], rest[1], rest[2]
    for c in range(3):  # x' = R[c,0] x + R[c,1] y + R[c,2] z + t[c]
        _muladd(g[:, 9 + c], g[:, 3 * c], x, tmp, scratch)
        _muladd(tmp, g[:, 3 * c + 1], y, tmp, scratch)
        _muladd(tmp, g[:, 3 * c + 2], z, target[..., c], scratch)


def per_joint_rows(transforms: Any, joints: Any = None) -> Any:
    """(J', B·12): per joint, every body's R00 R01 ... R22 tx ty tz, from (B, J, 12) transforms;
    ``joints`` selects some joints first (None: all)."""
    t = transforms if joints is None else transforms[:, joints]
    t = t.permute(1, 0, 2) if is_torch(t) else t.transpose(1, 0, 2)
    return t.reshape(t.shape[0], -1)


def block_rows(per_joint: Any, block: VertexBlock) -> Any:
    """The rows of :func:`per_joint_rows` (all joints) that ``block`` uses."""
    return per_joint if block.joints is None else per_joint[block.joints]


def _matmul(a: Any, b: Any, out: Any) -> Any:
    if is_torch(a):
        return sys.modules["torch"].mm(a, b, out=out)
    return np.matmul(a, b, out=out)


def _muladd(a: Any, b: Any, c: Any, out: Any, scratch: Any) -> None:
    """``out = a + b * c`` (``scratch`` holds ``b * c`` in NumPy; torch fuses it)."""
    if is_torch(a):
        sys.modules["torch"].addcmul(a, b, c, out=out)
    else:
        np.multiply(b, c, out=scratch)
        np.add(a, scratch, out=out)


def empty(shape: tuple[int, ...], like: Any) -> Any:
    """An uninitialised array like ``like``.

    Large torch CPU buffers are allocated by NumPy, which asks the kernel for transparent huge pages
    (``madvise``): first-touch page faults then cost a fraction of those of torch's own allocation,
    a measured 15–25 % of a B = 512 forward pass.
    """
    if not is_torch(like):
        return np.empty(shape, dtype=like.dtype)
    torch = sys.modules["torch"]
    np_dtype = {torch.float32: np.float32, torch.float64: np.float64}.get(like.dtype)
    if like.device.type == "cpu" and np_dtype is not None and math.prod(shape) * like.element_size() >= 1 << 22:
        return torch.from_numpy(np.empty(shape, dtype=np_dtype))
    return torch.empty(shape, dtype=like.dtype, device=like.device)


def _contiguous(x: Any) -> Any:
    return x.contiguous() if is_torch(x) else np.ascontiguousarray(x)


def _to_numpy(x: Any) -> np.ndarray:
    return x.detach().cpu().numpy() if is_torch(x) else np.asarray(x)
