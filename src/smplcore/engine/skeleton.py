"""The kinematic chain: local joint rotations to world transforms, computed level by level."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from smplcore.engine.backend import for_cache, index, is_torch, namespace


@dataclass(frozen=True, eq=False)
class KinematicTree:
    """A joint tree reordered by depth, so that each depth level is one batched matrix product.

    Attributes
    ----------
    parents : parent of each joint, -1 for the root.
    order : the joints sorted by depth (stable); each level is a contiguous run of it.
    level_bounds : ``(start, stop)`` of each level within ``order``.
    parent_slots : for each level after the first, the position of each joint's parent within
        the previous level.
    order_inverse : position of each joint within ``order``.
    """

    parents: tuple[int, ...]
    order: tuple[int, ...]
    level_bounds: tuple[tuple[int, int], ...]
    parent_slots: tuple[tuple[int, ...], ...]
    order_inverse: tuple[int, ...]
    _index_cache: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def from_parents(cls, parents: Sequence[int] | np.ndarray) -> KinematicTree:
        parents = tuple(int(p) for p in parents)
        if not parents or parents[0] != -1:
            raise ValueError("parents: the first joint must be the root (parent -1)")
        depth = [0] * len(parents)
        for j, p in enumerate(parents[1:], start=1):
            if not 0 <= p < j:
                raise ValueError(f"parents: joint {j} has parent {p}; parents must come before their children")
            depth[j] = depth[p] + 1
        levels = [[j for j in range(len(parents)) if depth[j] == d] for d in range(max(depth) + 1)]
        order = tuple(j for level in levels for j in level)
        bounds, start = [], 0
        for level in levels:
            bounds.append((start, start + len(level)))
            start += len(level)
        slots = tuple(tuple(levels[d - 1].index(parents[j]) for j in levels[d]) for d in range(1, len(levels)))
        inverse = tuple(int(i) for i in np.argsort(order))
        return cls(parents, order, tuple(bounds), slots, inverse)

    def chain_to_root(self, joint: int) -> list[int]:
        """``joint``, its parent, ..., the root."""
        chain = []
        while joint != -1:
            chain.append(joint)
            joint = self.parents[joint]
        return chain

    def indices(self, like: Any) -> dict[str, Any]:
        """The tree's index arrays in the namespace and on the device of ``like`` (cached)."""
        key = (type(like).__module__, str(getattr(like, "device", "cpu")))
        cached = self._index_cache.get(key)
        if cached is None:
            with for_cache():
                cached = self._make_indices(like)
            self._index_cache[key] = cached
        return cached

    def _make_indices(self, like: Any) -> dict[str, Any]:
        identity = self.order == tuple(range(len(self.order)))
        return {
            "order": None if identity else index(self.order, like),
            "inverse": None if identity else index(self.order_inverse, like),
            "parents": index([max(p, 0) for p in self.parents], like),
            "slots": [index(s, like) for s in self.parent_slots],
        }


def world_transforms(rotmats: Any, joints: Any, tree: KinematicTree) -> tuple[Any, Any]:
    """Compose local rotations along the tree.

    Parameters
    ----------
    rotmats : (B, J, 3, 3) local rotation of each joint.
    joints : (B, J, 3) rest-pose joint positions.
    tree : the kinematic tree.

    Returns
    -------
    world_rot : (B, J, 3, 3) rotation of each joint in the world.
    world_pos : (B, J, 3) posed joint positions.
    """
    idx = tree.indices(rotmats)
    offsets = joints - joints[:, idx["parents"]]  # the root's own "offset" is zero; replaced below
    offsets = namespace(rotmats).concat([joints[:, :1], offsets[:, 1:]], axis=1)
    if idx["order"] is not None:
        rotmats, offsets = rotmats[:, idx["order"]], offsets[:, idx["order"]]
    world_rot, world_pos = chain(rotmats, offsets, tree)
    if idx["inverse"] is not None:
        world_rot, world_pos = world_rot[:, idx["inverse"]], world_pos[:, idx["inverse"]]
    return world_rot, world_pos


def chain(rotmats: Any, offsets: Any, tree: KinematicTree) -> tuple[Any, Any]:
    """:func:`world_transforms` on joints already in depth order (``tree.order``).

    ``rotmats`` (B, J, 3, 3) local rotations and ``offsets`` (B, J, 3) rest offsets from the parent
    (the root's: its position); returns world rotations and positions in the same order.
    """
    xp = namespace(rotmats)
    idx = tree.indices(rotmats)
    start, stop = tree.level_bounds[0]
    level_rot, level_pos = [rotmats[:, start:stop]], [offsets[:, start:stop]]
    for (start, stop), slots in zip(tree.level_bounds[1:], idx["slots"]):
        parent_rot = level_rot[-1][:, slots]
        level_rot.append(parent_rot @ rotmats[:, start:stop])
        level_pos.append((parent_rot @ offsets[:, start:stop, :, None])[..., 0] + level_pos[-1][:, slots])
    return xp.concat(level_rot, axis=1), xp.concat(level_pos, axis=1)


def skinning_transforms(world_rot: Any, world_pos: Any, rest_joints: Any) -> Any:
    """Per-joint transforms relative to the rest pose, as (B, J, 12): 9 rotation entries, then translation.

    A rest-pose point ``v`` near joint ``j`` moves to ``world_rot[j] @ (v - rest_joints[j]) + world_pos[j]``.
    """
    xp = namespace(world_rot)
    batch, num_joints = world_rot.shape[:2]
    translation = world_pos - (world_rot @ rest_joints[..., None])[..., 0]
    return xp.concat([world_rot.reshape(batch, num_joints, 9), translation], axis=-1)


def with_translation(transforms: Any, translation: Any | None) -> Any:
    """(B, J, 12) transforms with (B, 3) ``translation`` added to their translation part (None: as is)."""
    if translation is None:
        return transforms
    return namespace(transforms).concat([transforms[..., :9], transforms[..., 9:] + translation[:, None]], axis=-1)


# Bodies skinned per chunk: the per-vertex transforms of one chunk (chunk × 12 × V values) stay
# in cache instead of streaming B × V × 12 values through memory.
_CHUNK_VALUES = 1 << 22


def records_gradients(*arrays: Any) -> bool:
    """Whether torch's autograd is recording operations on any of ``arrays``."""
    if not is_torch(arrays[0]):
        return False
    import torch

    return torch.is_grad_enabled() and any(a.requires_grad for a in arrays)


def skin(vertices: Any, transforms: Any, weights_t: Any, translation: Any = None) -> Any:
    """Linear blend skinning.

    Parameters
    ----------
    vertices : (B, 3, V) rest-pose vertices (shaped, with pose correctives), one row per coordinate.
    transforms : (B, J, 12) from :func:`skinning_transforms`.
    weights_t : (J, V) skinning weights, transposed.
    translation : (B, 3) added to every vertex, or None.

    Returns
    -------
    (B, V, 3) posed vertices.
    """
    xp = namespace(transforms)
    batch, num_joints = transforms.shape[:2]
    num_verts = weights_t.shape[1]
    transforms = with_translation(transforms, translation)
    if records_gradients(vertices, transforms):
        # Training: blended transforms, then one batched 3x3 product per vertex; its backward is two
        # products, where the per-coordinate expressions below would record a dozen elementwise ops.
        blended = weights_t.mT @ transforms  # (B, V, 12)
        rot = blended[..., :9].reshape(batch, num_verts, 3, 3)
        return (rot @ vertices.mT[..., None])[..., 0] + blended[..., 9:]
    per_vertex = transforms.mT.reshape(batch * 12, num_joints)  # rows: R00 R01 ... R22 tx ty tz per body
    chunk = max(1, _CHUNK_VALUES // (12 * max(num_verts, 1)))
    out = []
    for start in range(0, batch, chunk):
        stop = min(start + chunk, batch)
        t = (per_vertex[12 * start : 12 * stop] @ weights_t).reshape(stop - start, 12, num_verts)
        x, y, z = vertices[start:stop, 0], vertices[start:stop, 1], vertices[start:stop, 2]
        out.append(
            xp.stack(
                [
                    t[:, 0] * x + t[:, 1] * y + t[:, 2] * z + t[:, 9],
                    t[:, 3] * x + t[:, 4] * y + t[:, 5] * z + t[:, 10],
                    t[:, 6] * x + t[:, 7] * y + t[:, 8] * z + t[:, 11],
                ],
                axis=-1,
            )
        )
    return out[0] if len(out) == 1 else xp.concat(out, axis=0)
