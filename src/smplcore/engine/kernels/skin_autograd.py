"""Linear blend skinning as one autograd node (torch only; imported when gradients are recorded).

Recorded op by op, skinning leaves a B×V×12 tensor of blended transforms, a batched product of
B·V tiny 3×3 matrices and the zero-filled gradients of its slices in the graph; the backward of
those tiny products is most of a training step. Here the forward and the backward are written out
on (bodies, vertices) planes:

* forward: ``G = transforms @ weights`` (one GEMM), then ``x' = G00 x + G01 y + G02 z + G03``, ...;
* backward, from ``g`` = d loss / d posed vertices:
  ``d rest_k = Σ_c G[c, k] g_c`` (multiply-adds on planes) and
  ``d transforms = (g_c · rest_k, g_c) @ weightsᵀ`` (one GEMM),

over blocks of vertices, with only the joints that weight a block, and chunks of bodies, so that
the per-vertex values stay in cache. ``G`` (B × 12 × V values, less than the B × V × 16 of a 4×4
formulation) is kept from the forward for the backward.
"""

from __future__ import annotations

import torch

from smplcore.engine.kernels import gemm
from smplcore.engine.kernels.blocked import apply_blended, blended_transforms, block_rows, empty, per_joint_rows

# Bodies per chunk: the chunk's bodies × 12 × block per-vertex values stay within a few MB.
_CHUNK_VALUES = 1 << 18


def _body_chunks(batch: int, block: int) -> list[slice]:
    step = max(1, _CHUNK_VALUES // max(block, 1))
    return [slice(b0, min(batch, b0 + step)) for b0 in range(0, batch, step)]


def tile_shapes(batch: int, blocks: tuple) -> list[tuple[int, int]]:
    """(bodies, vertices) of each tile of blended transforms, in the order :func:`skin_forward` makes them."""
    return [(sl.stop - sl.start, b.stop - b.start) for b in blocks for sl in _body_chunks(batch, b.stop - b.start)]


def skin_forward(
    rest: torch.Tensor, transforms: torch.Tensor, blocks: tuple, separate_tiles: bool = False
) -> tuple[torch.Tensor, list[torch.Tensor]]:
    """(B, V, 3) skinned vertices and the tiles of blended transforms, (bodies, 12, block) each, that
    :func:`skin_backward` needs. ``separate_tiles``: each tile its own tensor (no shared buffer)."""
    batch, _, num_verts = rest.shape
    per_joint = per_joint_rows(transforms)
    out = empty((batch, num_verts, 3), rest)
    # the blended transforms of each (vertex block, body chunk), kept for the backward: oneDNN's
    # outputs where the weights are packed, else one buffer (in huge pages, see blocked.empty)
    packed = all(b.packed_weights is not None for b in blocks)
    store = None if packed or separate_tiles else empty((12 * batch * num_verts,), rest)
    tiles, offset = [], 0
    for block in blocks:
        cols, rows = slice(block.start, block.stop), block_rows(per_joint, block)
        n = block.stop - block.start
        for sl in _body_chunks(batch, n):
            m = sl.stop - sl.start
            if store is not None:
                chunk_store = store[offset:]
            else:
                chunk_store = None if block.packed_weights is not None else empty((12 * m * n,), rest)
            g = blended_transforms(rows[:, 12 * sl.start : 12 * sl.stop].T, block, chunk_store, m * n)
            g, offset = g.view(m, 12, n), offset + 12 * m * n
            tiles.append(g)
            chunk_rest = rest[sl, :, cols].transpose(0, 1)  # (3, bodies, block)
            apply_blended(g, chunk_rest, out[sl, cols], torch.empty_like(chunk_rest[0]))
    return out, tiles


def skin_backward(
    rest: torch.Tensor,
    transforms: torch.Tensor,
    blocks: tuple,
    tiles: list[torch.Tensor],
    grad_out: torch.Tensor,
    needs: tuple[bool, bool],
) -> tuple[torch.Tensor | None, torch.Tensor | None]:
    """Gradients with respect to ``rest`` and ``transforms`` (where ``needs`` says) from ``grad_out``,
    the gradient of :func:`skin_forward`'s vertices, and its tiles."""
    batch = rest.shape[0]
    grad_planes = empty(rest.shape, rest)  # (B, 3, V): d/dx', d/dy', d/dz'
    grad_planes.copy_(grad_out.permute(0, 2, 1))
    grad_rest = empty(rest.shape, rest) if needs[0] else None
    widest = max(b.stop - b.start for b in blocks)
    plane_store = empty((12 * min(batch * widest, max(_CHUNK_VALUES, widest)),), rest)  # a chunk's planes
    grad_per_joint = None
    if needs[1]:
        grad_per_joint = torch.zeros(transforms.shape[1], batch * 12, dtype=rest.dtype, device=rest.device)
    tile_iter = iter(tiles)
    for block in blocks:
        cols, n = slice(block.start, block.stop), block.stop - block.start
        for sl in _body_chunks(batch, n):
            g, g_out = next(tile_iter), grad_planes[sl, :, cols]
            if grad_rest is not None:
                for k in range(3):  # d rest_k = G[0,k] g_x + G[1,k] g_y + G[2,k] g_z
                    d = torch.mul(g[:, k], g_out[:, 0], out=grad_rest[sl, k, cols])
                    d.addcmul_(g[:, 3 + k], g_out[:, 1]).addcmul_(g[:, 6 + k], g_out[:, 2])
            if grad_per_joint is not None:  # d G[c,k] = g_c rest_k, d G[c,3] = g_c; then to the joints
                m = g_out.shape[0]
                planes = plane_store[: 12 * m * n].view(m, 12, n)
                torch.mul(g_out[:, :, None], rest[sl, None, :, cols], out=planes[:, :9].view(m, 3, 3, n))
                planes[:, 9:] = g_out
                planes = planes.reshape(m * 12, n)
                if block.packed_weights_t is not None:  # (joints of the block, m·12)
                    contribution = gemm.product(planes, block.packed_weights_t).T
                else:
                    contribution = block.weights_t @ planes.T
                target = grad_per_joint[:, 12 * sl.start : 12 * sl.stop]
                if block.joints is None:
                    target += contribution
                else:
                    target.index_add_(0, block.joints, contribution)
    grad_transforms = None
    if grad_per_joint is not None:
        grad_transforms = grad_per_joint.reshape(-1, batch, 12).permute(1, 0, 2)
    return grad_rest, grad_transforms


class _Skin(torch.autograd.Function):
    @staticmethod
    def forward(ctx, rest: torch.Tensor, transforms: torch.Tensor, blocks: tuple) -> torch.Tensor:
        out, tiles = skin_forward(rest, transforms, blocks)
        ctx.save_for_backward(rest, transforms)
        ctx.blocks, ctx.tiles = blocks, tiles
        return out

    @staticmethod
    def backward(ctx, grad_out: torch.Tensor):
        rest, transforms = ctx.saved_tensors
        needs = (ctx.needs_input_grad[0], ctx.needs_input_grad[1])
        return (*skin_backward(rest, transforms, ctx.blocks, ctx.tiles, grad_out, needs), None)


def skin_with_gradients(rest: torch.Tensor, transforms: torch.Tensor, blocks: tuple) -> torch.Tensor:
    """(B, V, 3) skinned vertices from (B, 3, V) rest vertices and (B, J, 12) transforms (translation
    folded in), differentiable in both. ``blocks`` (:func:`smplcore.engine.blocked.vertex_blocks`)
    hold the constant weights, cut into vertex blocks with the joints each block uses."""
    return _Skin.apply(rest, transforms, blocks)
