"""smplx's constructor keywords: which set up the model, which create parameters, which are only accepted.

Any keyword that some smplx 0.1.28 class accepts is taken silently (real code passes one config dict to
every class); an unknown keyword warns once per name, with a "did you mean" where it is close to a known one.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from typing import Any

from smplcore.frontend import SETUP_OPTIONS, warn_once

#: Every keyword of smplx 0.1.28's model constructors and ``create`` (a fact about its API).
SMPLX_CONSTRUCTOR_KEYWORDS = frozenset(
    {
        "age",
        "batch_size",
        "betas",
        "body_pose",
        "create_betas",
        "create_body_pose",
        "create_expression",
        "create_global_orient",
        "create_hand_pose",
        "create_jaw_pose",
        "create_left_hand_pose",
        "create_leye_pose",
        "create_neck_pose",
        "create_reye_pose",
        "create_right_hand_pose",
        "create_transl",
        "data_struct",
        "dtype",
        "expression",
        "ext",
        "flat_hand_mean",
        "gender",
        "global_orient",
        "hand_pose",
        "is_rhand",
        "jaw_pose",
        "joint_mapper",
        "kid_template_path",
        "left_hand_pose",
        "leye_pose",
        "model_path",
        "model_type",
        "neck_pose",
        "num_betas",
        "num_expression_coeffs",
        "num_pca_comps",
        "reye_pose",
        "right_hand_pose",
        "transl",
        "use_compressed",
        "use_face_contour",
        "use_pca",
        "v_template",
        "vertex_ids",
        "use_hands",
        "use_feet_keypoints",
    }
)
#: Every keyword of smplx 0.1.28's forward methods.
SMPLX_FORWARD_KEYWORDS = frozenset(
    {
        "betas",
        "body_pose",
        "expression",
        "global_orient",
        "hand_pose",
        "jaw_pose",
        "left_hand_pose",
        "leye_pose",
        "neck_pose",
        "pose2rot",
        "return_full_pose",
        "return_shaped",
        "return_verts",
        "reye_pose",
        "right_hand_pose",
        "transl",
    }
)
# smplcore's own keywords, known besides smplx's.
OWN_KEYWORDS = frozenset({"kernel", "fix_left_shapedirs", "data", "check_finite", "check_rotations", "uv_path"})


def split_keywords(
    owner: str, kwargs: dict[str, Any], parameters: Iterable[str]
) -> tuple[dict[str, Any], dict[str, Any], dict[str, bool]]:
    """``kwargs`` of a constructor as (setup options, initial parameter values, ``create_*`` flags).

    Keywords that smplx accepts but this class does not use are dropped silently; unknown ones warn.
    """
    parameters = tuple(parameters)
    setup = {k: kwargs.pop(k) for k in list(kwargs) if k in SETUP_OPTIONS}
    initial = {k: kwargs.pop(k) for k in list(kwargs) if k in parameters}
    create = {k: bool(kwargs.pop(f"create_{k}", True)) for k in parameters}
    warn_unknown(owner, set(kwargs) - SMPLX_CONSTRUCTOR_KEYWORDS - OWN_KEYWORDS)
    return setup, initial, create


def warn_unknown(owner: str, unknown: Iterable[str], *, forward: bool = False) -> None:
    """One warning per unknown keyword name (per owner and process), with a close match where there is one."""
    known = sorted(
        (SMPLX_FORWARD_KEYWORDS | {"kernel", "check_finite", "check_rotations"})
        if forward
        else (SMPLX_CONSTRUCTOR_KEYWORDS | OWN_KEYWORDS)
    )
    for name in sorted(unknown):
        if forward and name in SMPLX_FORWARD_KEYWORDS:
            continue  # accepted by another smplx class (e.g. hand_pose given to SMPL): ignored silently
        close = difflib.get_close_matches(name, known, n=1, cutoff=0.8)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        warn_once(owner, f"{owner}: ignoring unknown keyword argument {name!r}{hint}", key=name)
