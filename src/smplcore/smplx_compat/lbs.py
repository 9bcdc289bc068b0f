"""smplx's ``lbs`` module API (``lbs``, ``blend_shapes``, ``batch_rodrigues``, ...) over smplcore's engine.

Torch functions with smplx's names, arguments and return shapes, for code that imports them
directly. They accept NumPy arrays too (the engine runs on both).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from smplcore.engine.backend import namespace
from smplcore.engine.landmarks import barycentric_points, contour_rows
from smplcore.engine.rotations import pose_features, rodrigues, y_angle
from smplcore.engine.skeleton import KinematicTree, skin, skinning_transforms, world_transforms

__all__ = [
    "lbs",
    "blend_shapes",
    "vertices2joints",
    "batch_rodrigues",
    "batch_rigid_transform",
    "transform_mat",
    "vertices2landmarks",
    "find_dynamic_lmk_idx_and_bcoords",
    "rot_mat_to_euler",
]


def _parents_list(parents: Any) -> list[int]:
    values = parents.tolist() if hasattr(parents, "tolist") else list(parents)
    values = [int(p) for p in values]
    values[0] = -1
    return values


def blend_shapes(betas: Any, shape_disps: Any) -> Any:
    """(B, V, 3) displacements: ``betas`` (B, K) times ``shape_disps`` (V, 3, K)."""
    return namespace(betas).einsum("bl,mkl->bmk", betas, shape_disps)


def vertices2joints(J_regressor: Any, vertices: Any) -> Any:
    """(B, J, 3) joints: ``J_regressor`` (J, V) applied to ``vertices`` (B, V, 3)."""
    return namespace(vertices).einsum("bik,ji->bjk", vertices, J_regressor)


def batch_rodrigues(rot_vecs: Any, epsilon: float = 1e-8, dtype: Any = None) -> Any:
    """(N, 3, 3) rotation matrices from (N, 3) axis-angle vectors (exact; ``epsilon`` is not needed)."""
    return rodrigues(rot_vecs)


def transform_mat(R: Any, t: Any) -> Any:
    """(B, 4, 4) homogeneous transforms from (B, 3, 3) rotations and (B, 3, 1) translations."""
    xp = namespace(R)
    top = xp.concat([R, t.reshape(*t.shape[:-2], 3, 1)], axis=-1)
    bottom = xp.zeros_like(top[..., :1, :])
    bottom[..., 0, 3] = 1
    return xp.concat([top, bottom], axis=-2)


def batch_rigid_transform(rot_mats: Any, joints: Any, parents: Any, dtype: Any = None) -> tuple[Any, Any]:
    """Posed joints (B, J, 3) and rest-relative transforms (B, J, 4, 4), as smplx returns them."""
    xp = namespace(rot_mats)
    joints = joints[..., 0] if joints.ndim == 4 or (joints.ndim == 3 and joints.shape[-1] == 1) else joints
    tree = KinematicTree.from_parents(_parents_list(parents))
    world_rot, world_pos = world_transforms(rot_mats, joints, tree)
    flat = skinning_transforms(world_rot, world_pos, joints)
    batch, num_joints = flat.shape[:2]
    rel = xp.concat([flat[..., :9].reshape(batch, num_joints, 3, 3), flat[..., 9:, None]], axis=-1)
    return world_pos, transform_mat(rel[..., :3], rel[..., 3:])


def lbs(
    betas: Any,
    pose: Any,
    v_template: Any,
    shapedirs: Any,
    posedirs: Any,
    J_regressor: Any,
    parents: Any,
    lbs_weights: Any,
    pose2rot: bool = True,
) -> tuple[Any, Any]:
    """smplx's ``lbs``: (B, V, 3) vertices and (B, J, 3) joints.

    ``pose`` is (B, 3 J) axis-angle, or rotation matrices (B, J, 3, 3) with ``pose2rot=False``;
    ``posedirs`` is (P, 3 V) as smplx stores it.
    """
    batch = max(betas.shape[0], pose.shape[0])
    v_shaped = v_template + blend_shapes(betas, shapedirs)
    joints = vertices2joints(J_regressor, v_shaped)
    rot_mats = rodrigues(pose.reshape(batch, -1, 3)) if pose2rot else pose.reshape(batch, -1, 3, 3)
    v_posed = v_shaped + (pose_features(rot_mats) @ posedirs).reshape(batch, -1, 3)
    tree = KinematicTree.from_parents(_parents_list(parents))
    world_rot, world_pos = world_transforms(rot_mats, joints, tree)
    verts = skin(v_posed.mT, skinning_transforms(world_rot, world_pos, joints), lbs_weights.T)
    return verts, world_pos


def vertices2landmarks(vertices: Any, faces: Any, lmk_faces_idx: Any, lmk_bary_coords: Any) -> Any:
    """(B, L, 3) landmarks from faces (F, 3), face indices (B, L) or (L,) and barycentrics."""
    return barycentric_points(vertices, faces[lmk_faces_idx], lmk_bary_coords)


def rot_mat_to_euler(rot_mats: Any) -> Any:
    """Rotation about Y of (N, 3, 3) matrices (radians)."""
    return y_angle(rot_mats)


def find_dynamic_lmk_idx_and_bcoords(
    vertices: Any,
    pose: Any,
    dynamic_lmk_faces_idx: Any,
    dynamic_lmk_b_coords: Any,
    neck_kin_chain: Sequence[int] | Any,
    pose2rot: bool = True,
) -> tuple[Any, Any]:
    """Faces (B, L) and barycentrics (B, L, 3) of the dynamic contour for the pose's head turn."""
    batch = vertices.shape[0]
    chain = [int(j) for j in (neck_kin_chain.tolist() if hasattr(neck_kin_chain, "tolist") else neck_kin_chain)]
    if pose2rot:
        aa = pose.reshape(batch, -1, 3)
        rot_mats = rodrigues(aa)
    else:
        rot_mats = pose.reshape(batch, -1, 3, 3)
    rows = contour_rows(rot_mats, chain)
    return dynamic_lmk_faces_idx[rows], dynamic_lmk_b_coords[rows]
