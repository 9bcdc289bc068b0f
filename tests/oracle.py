"""The oracle for tests: a model's outputs computed plainly, in float64 NumPy, from its file's arrays.

Inputs are handled here from the options directly (hand PCA, mean pose, coefficient padding), and the
forward is :mod:`smplcore.engine.reference`; nothing of the fast paths or the front ends is used.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from smplcore.engine import reference
from smplcore.engine.landmarks import contour_rows
from smplcore.family.specs import extra_joint_vertex_ids, get_spec


def oracle(
    data: Any,
    params: dict[str, np.ndarray],
    *,
    num_betas: int = 10,
    num_expression_coeffs: int = 10,
    use_pca: bool = True,
    num_pca_comps: int = 6,
    flat_hand_mean: bool = False,
    use_face_contour: bool = False,
    rotation_matrices: bool = False,
    skinning: str = "lbs",
) -> tuple[np.ndarray, np.ndarray]:
    """(B, V, 3) vertices and (B, J', 3) output joints (skeleton, extra vertex joints, landmarks), translated."""
    spec = get_spec(data.model_type)
    p = {k: np.asarray(v, np.float64) for k, v in params.items() if v is not None}
    batch = max([v.shape[0] for v in p.values()] + [1])
    num_betas = min(num_betas, data.num_betas)

    def padded(name: str, width: int) -> np.ndarray:
        out = np.zeros((batch, width))
        if name in p:
            out[:, : p[name].shape[1]] = p[name]
        return out

    coeffs = [padded("betas", num_betas)]
    dirs = [np.asarray(data.shapedirs, np.float64)[:, :, :num_betas]]
    if spec.has_expression:
        num_expression_coeffs = min(num_expression_coeffs, data.num_expression_coeffs)
        coeffs.append(padded("expression", num_expression_coeffs))
        dirs.append(np.asarray(data.exprdirs, np.float64)[:, :, :num_expression_coeffs])
    blocks = []
    for block in spec.pose_blocks:
        value = p.get(block.name)
        if rotation_matrices:
            blocks.append(
                np.broadcast_to(np.eye(3), (batch, block.num_joints, 3, 3))
                if value is None
                else value.reshape(batch, block.num_joints, 3, 3)
            )
            continue
        aa = np.zeros((batch, 3 * block.num_joints)) if value is None else value.reshape(batch, -1)
        if block.hand:
            side = data.gender if block.hand == "self" else block.hand
            if use_pca and value is not None:
                aa = aa @ np.asarray(getattr(data, f"hands_components_{side}"), np.float64)[:num_pca_comps]
            mean = getattr(data, f"hands_mean_{side}")
            if not flat_hand_mean and mean is not None:
                aa = aa + np.asarray(mean, np.float64)
        blocks.append(reference.rodrigues(aa.reshape(batch, -1, 3)))
    rotmats = np.concatenate(blocks, axis=1)
    posedirs = (
        None if data.posedirs is None else np.asarray(data.posedirs, np.float64).reshape(-1, data.posedirs.shape[-1]).T
    )
    verts, joints, _ = reference.forward(
        np.asarray(data.v_template, np.float64),
        np.concatenate(dirs, axis=-1),
        posedirs,
        np.asarray(data.J_regressor, np.float64),
        [int(x) for x in data.parents],
        np.asarray(data.weights, np.float64),
        np.concatenate(coeffs, axis=1),
        rotmats,
        skinning,
    )
    parts = [joints]
    if spec.extra_joints:
        ids = spec.vertex_ids or dict(zip(_extra_keys(data), data.extra_joint_vertex_ids))
        parts.append(verts[:, extra_joint_vertex_ids(ids, True, True)[1]])
    if spec.landmarks:
        corners = data.faces[data.lmk_faces_idx]
        parts.append(np.einsum("lk,blkd->bld", data.lmk_bary_coords, verts[:, corners]))
        if use_face_contour:
            from smplcore.engine.skeleton import KinematicTree

            chain = KinematicTree.from_parents(data.parents).chain_to_root(spec.neck_index)
            rows = contour_rows(rotmats, chain)
            corners = data.faces[data.dynamic_lmk_faces_idx][rows]  # (B, 17, 3)
            pts = verts[np.arange(batch)[:, None, None], corners]
            parts.append(np.einsum("blk,blkd->bld", data.dynamic_lmk_bary_coords[rows], pts))
    joints = np.concatenate(parts, axis=1)
    if "transl" in p:
        verts, joints = verts + p["transl"][:, None], joints + p["transl"][:, None]
    return verts, joints


def _extra_keys(data: Any) -> list[str]:
    from smplcore.family import names

    return [names.EXTRA_JOINT_KEYS[n] for n in data.extra_joint_names]
