"""smplx's buffers on a torch body module, registered in smplx's order (``named_buffers()``, ``state_dict()``), and
its NumPy hand PCA attributes."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from smplcore.family import names as family_names
from smplcore.family.specs import FamilySpec
from smplcore.frontend import ModelSetup
from smplcore.io.model_data import ModelData
from smplcore.torch.selector import VertexJointSelector

__all__ = ["hand_buffer", "numpy_hand_components", "register_buffers"]


def hand_buffer(block: str, kind: str) -> str:
    """smplx's buffer names: ``left_hand_components``, ``right_hand_mean``, ``hand_mean``, ..."""
    return block.replace("_pose", "") + "_" + kind


def register_buffers(
    module: Any, setup: ModelSetup, dtype: torch.dtype, templates: np.ndarray | None, use_hands: bool
) -> None:
    """Register smplx's buffers of ``module`` (a body module of ``setup``'s family) in ``dtype``, and its
    ``vertex_joint_selector``; ``templates`` (B, V, 3) is a per-body ``v_template`` (None: the setup's)."""
    d, spec = setup.data, setup.spec

    def as_float(a: Any) -> torch.Tensor:
        return torch.tensor(np.asarray(a), dtype=dtype)

    # smplx's order of registration: the SMPL arrays, the hands, then for FLAME the expression basis before the
    # landmarks, for SMPL-X after them
    module.register_buffer("shapedirs", as_float(setup.shapedirs))
    module.register_buffer("faces_tensor", torch.tensor(np.asarray(d.faces), dtype=torch.long))
    module.register_buffer("v_template", as_float(d.v_template if templates is None else templates))
    module.register_buffer("J_regressor", as_float(d.J_regressor))
    num_posedirs = 9 * (d.num_joints - 1)
    posedirs = (
        np.zeros((num_posedirs, 3 * d.num_vertices))
        if d.posedirs is None
        else np.asarray(d.posedirs).reshape(-1, d.posedirs.shape[-1]).T
    )
    module.register_buffer("posedirs", as_float(posedirs))
    module.register_buffer("parents", torch.tensor(np.asarray(d.parents), dtype=torch.long))
    module.register_buffer("lbs_weights", as_float(d.weights))
    if setup.dmpldirs is not None:  # dmpl_path= only (human_body_prior's name): smplx's state_dict otherwise
        module.register_buffer("dmpldirs", as_float(setup.dmpldirs))
    extra = list(family_names.VERTEX_IDS_MANO.values()) if spec.model_type == "mano" else list(setup.extra_joint_ids)
    module.vertex_joint_selector = VertexJointSelector(extra, use_hands=bool(use_hands))
    for block, comps in setup.hand_components.items():
        module.register_buffer(hand_buffer(block, "components"), as_float(comps))
    for block, mean in setup.hand_means.items():
        module.register_buffer(hand_buffer(block, "mean"), as_float(mean))
    if setup.hand_means:
        module.register_buffer("pose_mean", as_float(setup.pose_mean))
    expression_first = spec.has_expression and not spec.hand_blocks  # FLAME
    if expression_first:
        module.register_buffer("expr_dirs", as_float(setup.exprdirs))
    if spec.landmarks:
        module.register_buffer("lmk_faces_idx", torch.tensor(d.lmk_faces_idx, dtype=torch.long))
        module.register_buffer("lmk_bary_coords", as_float(d.lmk_bary_coords))
        if setup.use_face_contour:
            module.register_buffer("dynamic_lmk_faces_idx", torch.tensor(d.dynamic_lmk_faces_idx, dtype=torch.long))
            module.register_buffer("dynamic_lmk_bary_coords", as_float(d.dynamic_lmk_bary_coords))
            module.register_buffer("neck_kin_chain", torch.as_tensor(setup.neck_chain, dtype=torch.long))
    if spec.has_expression and not expression_first:
        module.register_buffer("expr_dirs", as_float(setup.exprdirs))
    if setup.regressor is not None:  # joint_regressors: not smplx's, so not in the state_dict
        ids = torch.as_tensor(setup.regressor.vertex_ids, dtype=torch.long)
        module.register_buffer("_regressor_ids", ids, persistent=False)
        module.register_buffer("_regressor_weights", as_float(setup.regressor.weights), persistent=False)


def numpy_hand_components(spec: FamilySpec, data: ModelData, num_pca_comps: int) -> dict[str, np.ndarray]:
    """smplx's ``np_left_hand_components`` / ``np_right_hand_components`` (``np_hand_components`` for MANO):
    the file's first ``num_pca_comps`` PCA components of each hand, whether or not PCA is used."""
    out = {}
    for block in spec.hand_blocks:
        side = data.gender if block.hand == "self" else block.hand
        comps = getattr(data, f"hands_components_{side}")
        if comps is not None:
            name = "np_hand_components" if block.hand == "self" else f"np_{side}_hand_components"
            out[name] = np.asarray(comps)[:num_pca_comps]
    return out
