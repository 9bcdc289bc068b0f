"""The fast kernels as torch custom operators, for ``torch.compile``.

Inductor cannot trace the fast kernels (oneDNN's packed products, the skinning node's hand-written
backward), so a compiled forward used to run the plain pass and came out slower than eager. Here the
heavy steps become opaque operators that a compiled graph calls as they are, while Inductor fuses
the small per-joint math around them (Rodrigues, the chain, pose features):

* ``smplcore::joint_basis``: the model's joint basis (:class:`~smplcore.engine.body.BodyArrays`);
* ``smplcore::skin_blocked``: the vertex-blocked inference pass (no autograd graph);
* ``smplcore::blend`` / ``smplcore::blend_t``: ``feats @ blend_basis`` and its transpose product;
* ``smplcore::skin`` / ``smplcore::skin_backward``: the skinning autograd node, forward and backward.

An operator takes tensors and plain values only, so a model's arrays are named by an integer
*handle*: :func:`register` gives one to a provider whose ``current()`` returns the up-to-date
:class:`~smplcore.engine.body.BodyArrays` (rebuilt after an edit of the buffers, eagerly, inside the
operator) and ``last()`` the latest ones without rebuilding (for output shapes while tracing).
"""

from __future__ import annotations

import itertools
import weakref
from typing import Any, Protocol

import torch

from smplcore.engine import body as engine
from smplcore.engine import reference
from smplcore.engine.kernels import blocked, skin_autograd


class Provider(Protocol):
    def current(self) -> engine.BodyArrays: ...

    def last(self) -> engine.BodyArrays: ...


_providers: dict[int, weakref.ref] = {}
_counter = itertools.count(1)


def register(provider: Provider) -> int:
    """A handle naming ``provider`` in the operators (forgotten when the provider is collected)."""
    handle = next(_counter)

    def forget(_: weakref.ref) -> None:
        _providers.pop(handle, None)

    _providers[handle] = weakref.ref(provider, forget)
    return handle


def _provider(handle: int) -> Provider:
    provider = _providers.get(handle)
    provider = None if provider is None else provider()
    if provider is None:
        raise RuntimeError(f"smplcore: no model is registered under handle {handle} (was it deleted?)")
    return provider


def _arrays(handle: int) -> engine.BodyArrays:
    return _provider(handle).current()


def _subset(arrays: engine.BodyArrays, ids: torch.Tensor | None) -> tuple[Any, Any, Any]:
    """Basis, transposed weights and vertex blocks of the mesh (``ids`` None) or of vertices ``ids``."""
    if ids is None:
        return arrays.blend_basis, arrays.weights_t, arrays.vertex_blocks
    basis, weights_t, blocks = arrays.vertex_subset(ids.cpu().numpy())
    return basis, weights_t, lambda size: blocks


def _num_vertices(handle: int, ids: torch.Tensor | None) -> int:
    return _provider(handle).last().weights_t.shape[1] if ids is None else ids.shape[0]


# --- the joint basis ---------------------------------------------------------------------------


@torch.library.custom_op("smplcore::joint_basis", mutates_args=())
def _joint_basis(handle: int, like: torch.Tensor) -> torch.Tensor:
    return _arrays(handle).joint_basis.to(like.dtype).clone()


@_joint_basis.register_fake
def _(handle: int, like: torch.Tensor) -> torch.Tensor:
    return like.new_empty(tuple(_provider(handle).last().joint_basis.shape))


# --- inference -------------------------------------------------------------------------------


@torch.library.custom_op("smplcore::skin_blocked", mutates_args=())
def _skin_blocked(handle: int, ids: torch.Tensor | None, feats: torch.Tensor, transforms: torch.Tensor) -> torch.Tensor:
    basis, weights_t, blocks = _subset(_arrays(handle), ids)
    size = blocked.block_size(feats.shape[0], weights_t.shape[1])
    return blocked.posed_vertices(feats.contiguous(), transforms.contiguous(), basis, blocks(size))


@_skin_blocked.register_fake
def _(handle: int, ids: torch.Tensor | None, feats: torch.Tensor, transforms: torch.Tensor) -> torch.Tensor:
    return feats.new_empty((feats.shape[0], _num_vertices(handle, ids), 3))


# --- under autograd: the blend product ----------------------------------------------------------


@torch.library.custom_op("smplcore::blend", mutates_args=())
def _blend(handle: int, ids: torch.Tensor | None, feats: torch.Tensor) -> torch.Tensor:
    arrays = _arrays(handle)
    basis = _subset(arrays, ids)[0][: feats.shape[1]]
    packed = arrays.packed_blend() if ids is None and feats.shape[1] == arrays.blend_basis.shape[0] else None
    if packed is not None:
        return blocked.gemm.product(feats.contiguous(), packed[0])
    return feats @ basis


@_blend.register_fake
def _(handle: int, ids: torch.Tensor | None, feats: torch.Tensor) -> torch.Tensor:
    return feats.new_empty((feats.shape[0], 3 * _num_vertices(handle, ids)))


@torch.library.custom_op("smplcore::blend_t", mutates_args=())
def _blend_t(handle: int, ids: torch.Tensor | None, grad: torch.Tensor, rows: int) -> torch.Tensor:
    arrays = _arrays(handle)
    basis = _subset(arrays, ids)[0][:rows]
    packed = arrays.packed_blend() if ids is None and rows == arrays.blend_basis.shape[0] else None
    if packed is not None:
        return blocked.gemm.product(grad.contiguous(), packed[1])
    return grad @ basis.T


@_blend_t.register_fake
def _(handle: int, ids: torch.Tensor | None, grad: torch.Tensor, rows: int) -> torch.Tensor:
    return grad.new_empty((grad.shape[0], rows))


def _blend_setup(ctx: Any, inputs: tuple, output: Any) -> None:
    ctx.handle, ctx.ids, ctx.rows = inputs[0], inputs[1], inputs[2].shape[1]


def _blend_backward(ctx: Any, grad: torch.Tensor) -> tuple:
    return None, None, _blend_t(ctx.handle, ctx.ids, grad, ctx.rows)


_blend.register_autograd(_blend_backward, setup_context=_blend_setup)


# --- under autograd: skinning -------------------------------------------------------------------


def _grad_blocks(arrays: engine.BodyArrays, ids: torch.Tensor | None, batch: int) -> tuple:
    weights_t, blocks = _subset(arrays, ids)[1:]
    few = batch <= engine._GRAD_FEW_BODIES
    return blocks(weights_t.shape[1] if few else engine._GRAD_BLOCK)


@torch.library.custom_op("smplcore::skin", mutates_args=())
def _skin(
    handle: int, ids: torch.Tensor | None, rest: torch.Tensor, transforms: torch.Tensor
) -> tuple[torch.Tensor, list[torch.Tensor]]:
    blocks = _grad_blocks(_arrays(handle), ids, rest.shape[0])
    out, tiles = skin_autograd.skin_forward(rest.contiguous(), transforms.contiguous(), blocks, separate_tiles=True)
    return out, tiles


@_skin.register_fake
def _(handle: int, ids: torch.Tensor | None, rest: torch.Tensor, transforms: torch.Tensor) -> tuple:
    batch = rest.shape[0]
    blocks = _grad_blocks(_provider(handle).last(), ids, batch)
    tiles = [rest.new_empty((m, 12, n)) for m, n in skin_autograd.tile_shapes(batch, blocks)]
    return rest.new_empty((batch, rest.shape[2], 3)), tiles


@torch.library.custom_op("smplcore::skin_backward", mutates_args=())
def _skin_backward(
    handle: int,
    ids: torch.Tensor | None,
    rest: torch.Tensor,
    transforms: torch.Tensor,
    tiles: list[torch.Tensor],
    grad_out: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor]:
    blocks = _grad_blocks(_arrays(handle), ids, rest.shape[0])
    grad_rest, grad_transforms = skin_autograd.skin_backward(
        rest, transforms, blocks, tiles, grad_out.contiguous(), (True, True)
    )
    assert grad_rest is not None and grad_transforms is not None  # both asked for
    return grad_rest, grad_transforms.contiguous()


@_skin_backward.register_fake
def _(handle, ids, rest, transforms, tiles, grad_out) -> tuple:
    return torch.empty_like(rest), torch.empty_like(transforms)


def _skin_setup(ctx: Any, inputs: tuple, output: Any) -> None:
    ctx.handle, ctx.ids = inputs[0], inputs[1]
    ctx.save_for_backward(inputs[2], inputs[3], *output[1])


def _skin_backward_rule(ctx: Any, grad_out: torch.Tensor, _grad_tiles: Any) -> tuple:
    rest, transforms, *tiles = ctx.saved_tensors
    grad_rest, grad_transforms = _skin_backward(ctx.handle, ctx.ids, rest, transforms, tiles, grad_out)
    return None, None, grad_rest, grad_transforms


_skin.register_autograd(_skin_backward_rule, setup_context=_skin_setup)


# --- the forward pass that a compiled graph runs ------------------------------------------------


def _skeleton(handle: int, arrays: engine.BodyArrays, coeffs: torch.Tensor, rotmats: torch.Tensor) -> tuple:
    """(B, 1 + K) ``[1, coeffs]``, (B, J, 3) posed joints and (B, J, 12) skinning transforms (depth order).

    The chain runs level by level as :func:`smplcore.engine.skeleton.chain` does, indexed by the tree's
    plain tuples (constants to the compiler)."""
    tree = arrays.tree
    batch, num_joints = coeffs.shape[0], len(tree.parents)
    with_one = torch.cat([torch.ones_like(coeffs[:, :1]), coeffs], dim=1)
    both = (with_one @ _joint_basis(handle, coeffs.detach())).reshape(batch, 2, num_joints, 3)
    rest, offsets = both[:, 0], both[:, 1]  # depth order
    local = rotmats[:, list(tree.order)]
    start, stop = tree.level_bounds[0]
    level_rot, level_pos = [local[:, start:stop]], [offsets[:, start:stop]]
    for (start, stop), slots in zip(tree.level_bounds[1:], tree.parent_slots):
        parent_rot = level_rot[-1][:, list(slots)]
        level_rot.append(parent_rot @ local[:, start:stop])
        level_pos.append((parent_rot @ offsets[:, start:stop, :, None])[..., 0] + level_pos[-1][:, list(slots)])
    world_rot, world_pos = torch.cat(level_rot, dim=1), torch.cat(level_pos, dim=1)
    translation = world_pos - (world_rot @ rest[..., None])[..., 0]
    transforms = torch.cat([world_rot.reshape(batch, num_joints, 9), translation], dim=-1)
    return with_one, world_pos[:, list(tree.order_inverse)], transforms


def joints(handle: int, arrays: engine.BodyArrays, coeffs: torch.Tensor, rotmats: torch.Tensor) -> torch.Tensor:
    """(B, J, 3) posed joints for (B, K) coefficients and (B, J, 3, 3) rotations (no mesh is built)."""
    return _skeleton(handle, arrays, coeffs, rotmats)[1]


def forward(
    handle: int,
    arrays: engine.BodyArrays,
    coeffs: torch.Tensor,
    rotmats: torch.Tensor,
    *,
    translation: torch.Tensor | None,
    gradients: bool,
    ids: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """(B, n, 3) posed vertices (translated; the mesh, or vertices ``ids``) and (B, J, 3) posed joints
    (untranslated), as :func:`smplcore.engine.body.forward` computes them, through the operators.

    ``arrays`` (the provider's latest) give only the tree and whether there are pose correctives;
    the numbers come from the operators, which read the current ones.
    """
    with_one, posed_joints, transforms = _skeleton(handle, arrays, coeffs, rotmats)
    fold = translation is not None and arrays.weights_sum_to_one  # exact only then (BodyArrays)
    if fold and translation is not None:
        transforms = torch.cat([transforms[..., :9], transforms[..., 9:] + translation[:, None]], dim=-1)
    feats = with_one
    if arrays.has_pose_correctives:
        feats = torch.cat([with_one, reference.pose_features(rotmats)], dim=1)
    if not gradients:
        verts = _skin_blocked(handle, ids, feats, transforms)
    else:
        rest = _blend(handle, ids, feats).reshape(coeffs.shape[0], 3, -1)
        verts = _skin(handle, ids, rest, transforms)[0]
    if translation is not None and not fold:
        verts = verts + translation[:, None]
    return verts, posed_joints
