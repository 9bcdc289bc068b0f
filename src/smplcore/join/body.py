"""The body side of joining: a body's local rotations from its parameters, its kinematic chain, and writing
joint rotations and hand poses back in the body model's own convention (PCA or full, flat or mean)."""

from __future__ import annotations

from typing import Any

import numpy as np

from smplcore.errors import ShapeError
from smplcore.join._rig import RigFacts
from smplcore.join.rotations import as_rotations, numpy_of, to_axis_angle, to_matrix

#: Pose blocks given as rotations of their joints (axis-angle, or matrices for the non-hand blocks).
HAND_BLOCKS = {"left": "left_hand_pose", "right": "right_hand_pose"}


def params_batch(params: dict[str, Any], *others: int) -> int:
    """The batch size of a parameter dict (rows of its 2-D+ arrays), broadcast with ``others``."""
    sizes = {int(np.shape(v)[0]) for v in params.values() if v is not None and np.ndim(v) >= 2}
    sizes |= set(others)
    sizes.discard(1)
    if len(sizes) > 1:
        raise ShapeError(f"body_params: batch sizes {sorted(sizes)} do not broadcast")
    return sizes.pop() if sizes else 1


def _rows(name: str, value: np.ndarray, batch: int) -> np.ndarray:
    if value.shape[0] not in (1, batch):
        raise ShapeError(f"{name}: expected {batch} (or 1) rows, got {value.shape[0]}")
    return np.broadcast_to(value, (batch,) + value.shape[1:]).copy()


def block_axis_angle(rig: RigFacts, params: dict[str, Any], name: str, batch: int) -> np.ndarray:
    """(B, 3 n) absolute axis-angle of pose block ``name`` (PCA expanded, the model's mean hand added).

    Hand blocks are PCA coefficients (B, C) or axis-angle (B, 45) as the model takes them; the other blocks
    axis-angle or rotation matrices.
    """
    block = rig.block(name)
    value = params.get(name)
    width = 3 * block.num_joints
    if value is None:
        out = np.zeros((1, width))
    elif name in rig.hand_components:
        value = np.atleast_2d(np.asarray(value, dtype=np.float64))
        if value.ndim != 2 or value.shape[1] != block.width:
            raise ShapeError(f"{name}: expected shape (B, {block.width}) (PCA coefficients), got {value.shape}")
        out = value @ rig.hand_components[name]
    elif name in HAND_BLOCKS.values():
        out = np.atleast_2d(np.asarray(value, dtype=np.float64))
        if out.ndim != 2 or out.shape[1] != width:
            raise ShapeError(f"{name}: expected shape (B, {width}) (axis-angle), got {out.shape}")
    else:
        out = to_axis_angle(as_rotations(name, value, block.num_joints)).reshape(-1, width)
    return _rows(name, out, batch) + rig.hand_means.get(name, 0.0)


def local_rotations(rig: RigFacts, params: dict[str, Any], batch: int) -> np.ndarray:
    """(B, J, 3, 3) local rotations of every joint of the body (hand means added)."""
    out = np.empty((batch, len(rig.parents), 3, 3))
    for block in rig.pose_blocks:
        aa = block_axis_angle(rig, params, block.name, batch)
        out[:, block.first_joint : block.first_joint + block.num_joints] = to_matrix(aa.reshape(batch, -1, 3))
    return out


def world_rotations(rig: RigFacts, local: np.ndarray) -> np.ndarray:
    """(B, J, 3, 3) world rotations of (B, J, 3, 3) local rotations through the tree (parents before children)."""
    world = np.empty_like(local)
    for j, parent in enumerate(rig.parents):
        world[:, j] = local[:, j] if parent < 0 else world[:, parent] @ local[:, j]
    return world


def rest_joints(rig: RigFacts, betas: Any, batch: int) -> np.ndarray:
    """(B, J, 3) rest joints for ``betas`` (narrower zero-padded, wider cut), or the template's joints."""
    joints = np.broadcast_to(rig.template_joints, (batch,) + rig.template_joints.shape).copy()
    if betas is not None and rig.joint_shapedirs.shape[-1]:
        b = np.atleast_2d(np.asarray(betas, dtype=np.float64))[:, : rig.joint_shapedirs.shape[-1]]
        joints += np.einsum("jck,bk->bjc", rig.joint_shapedirs[..., : b.shape[1]], _rows("betas", b, batch))
    return joints


def joint_positions(rig: RigFacts, params: dict[str, Any], world: np.ndarray) -> np.ndarray:
    """(B, J, 3) posed joint positions (rigid chain of the shaped rest joints, plus ``transl``)."""
    batch = world.shape[0]
    rest = rest_joints(rig, params.get("betas"), batch)
    pos = np.empty_like(rest)
    for j, parent in enumerate(rig.parents):
        if parent < 0:
            pos[:, j] = rest[:, j]
        else:
            pos[:, j] = pos[:, parent] + np.einsum("bij,bj->bi", world[:, parent], rest[:, j] - rest[:, parent])
    transl = params.get("transl")
    if transl is not None:
        pos += _rows("transl", np.atleast_2d(np.asarray(transl, dtype=np.float64)), batch)[:, None]
    return pos


def hand_block_value(rig: RigFacts, side: str, absolute: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The body's ``{side}_hand_pose`` value for (B, 45) absolute finger axis-angle, in the model's convention.

    Returns the value (B, width) and (B,) the norm of what the body's PCA space cannot hold (0 for full poses).
    """
    name = HAND_BLOCKS[side]
    relative = absolute - rig.hand_means.get(name, 0.0)
    comps = rig.hand_components.get(name)
    if comps is None:
        return relative, np.zeros(absolute.shape[0])
    coeffs = np.linalg.lstsq(comps.T, relative.T, rcond=None)[0].T
    return coeffs, np.linalg.norm(relative - coeffs @ comps, axis=1)


def set_joint(rig: RigFacts, params: dict[str, Any], joint: int, rotation: np.ndarray, batch: int) -> None:
    """Write (B, 3, 3) ``rotation`` as joint ``joint``'s local axis-angle into its block of ``params``."""
    for block in rig.pose_blocks:
        if block.first_joint <= joint < block.first_joint + block.num_joints and block.name not in HAND_BLOCKS.values():
            aa = block_axis_angle(rig, params, block.name, batch)
            k = joint - block.first_joint
            aa[:, 3 * k : 3 * k + 3] = to_axis_angle(rotation)
            params[block.name] = aa
            return
    raise ValueError(f"joint {joint} is in no rotation block of the {rig.model_type} model")


def copy_params(body_params: dict[str, Any], batch_of: tuple[int, ...] = ()) -> tuple[dict[str, Any], int]:
    """A float64 copy of ``body_params`` with every rotation block (not the hands) as (B, 3 n) axis-angle rows,
    and the batch size (broadcast with ``batch_of``)."""
    if not isinstance(body_params, dict):
        raise TypeError(f"body_params: expected a dict of the body model's keywords, got {type(body_params).__name__}")
    params = {k: np.array(numpy_of(v)) for k, v in body_params.items() if v is not None}
    return params, params_batch(params, *batch_of)


def rotations_as_axis_angle(rig: RigFacts, params: dict[str, Any], batch: int) -> None:
    """Rewrite the non-hand rotation blocks of ``params`` (and ``body_pose``) as (B, 3 n) axis-angle rows."""
    for block in rig.pose_blocks:
        if block.name not in HAND_BLOCKS.values() and (block.name in params or block.name == "body_pose"):
            params[block.name] = block_axis_angle(rig, params, block.name, batch)
