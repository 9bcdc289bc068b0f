"""SMPL-X files (v1.0 / v1.1 layouts, npz and pkl) and the kid templates."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .body import _smpl_arrays
from .meshes import _bary, _core, _expression, _hand_pca, _head_faces, _left_from_right_pca, _norm_gender, _seam_uvs
from .pickles import _npz, _object0, dump_legacy_pickle
from .sizes import _GENDER_SCALE, SMPLX_FACES, SMPLX_UVS, SMPLX_VERTS
from .skeletons import _FINGER_ORDER, _smplx_skel

_SMPLX_JOINT_NAMES = [
    "pelvis",
    "left_hip",
    "right_hip",
    "spine1",
    "left_knee",
    "right_knee",
    "spine2",
    "left_ankle",
    "right_ankle",
    "spine3",
    "left_foot",
    "right_foot",
    "neck",
    "left_collar",
    "right_collar",
    "head",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "jaw",
    "left_eye_smplhf",
    "right_eye_smplhf",
] + [f"{side}_{finger}{k}" for side in ("left", "right") for finger in _FINGER_ORDER for k in (1, 2, 3)]


def _smplx_arrays(gender: str, seed: int, layout: str):
    g = _norm_gender(gender)
    skel = _smplx_skel(_GENDER_SCALE[g])
    rng, mesh, d = _core("smplx", g, seed, SMPLX_VERTS, SMPLX_FACES, skel, 300, 0.02, 2e-3)
    expr = _expression(rng, mesh, skel, 100, 4e-3)
    if layout == "1.1":
        d["shapedirs"] = np.concatenate([d["shapedirs"], expr], axis=2)
    elif layout == "1.0":
        d["shapedirs"] = np.concatenate([d["shapedirs"][:, :, :10], expr[:, :, :10]], axis=2)
    else:
        raise ValueError("layout must be '1.0' or '1.1'")
    del d["J"]
    comps_r, mean_r, coeffs_r = _hand_pca(seed)
    comps_l, mean_l, coeffs_l = _left_from_right_pca(comps_r, mean_r, coeffs_r)
    d.update(
        hands_componentsl=comps_l,
        hands_componentsr=comps_r,
        hands_meanl=mean_l,
        hands_meanr=mean_r,
        hands_coeffsl=coeffs_l,
        hands_coeffsr=coeffs_r,
    )
    front = _head_faces(mesh, skel, d["f"], front=True)
    allhead = _head_faces(mesh, skel, d["f"], front=False)
    d["lmk_faces_idx"] = rng.choice(front, 51, replace=False).astype(np.int64)
    d["lmk_bary_coords"] = _bary(rng, 51)
    d["dynamic_lmk_faces_idx"] = rng.choice(allhead, (79, 17)).astype(np.int64)
    d["dynamic_lmk_bary_coords"] = _bary(rng, (79, 17))
    d["vt"], d["ft"] = _seam_uvs(rng, mesh.v, d["f"], SMPLX_UVS)
    d["joint2num"] = {n: i for i, n in enumerate(_SMPLX_JOINT_NAMES)}
    parts = [
        "global",
        "head",
        "leftCalf",
        "leftFingers",
        "leftFoot",
        "leftForeArm",
        "leftHand",
        "leftShoulder",
        "leftThigh",
        "leftToes",
        "leftUpperArm",
        "neck",
        "rightCalf",
        "rightFingers",
        "rightFoot",
        "rightForeArm",
        "rightHand",
        "rightShoulder",
        "rightThigh",
        "rightToes",
        "rightUpperArm",
        "spine",
        "spine1",
        "spine2",
        "leftEye",
        "rightEye",
        "jaw",
    ]
    d["part2num"] = {n: i for i, n in enumerate(parts)}
    return mesh, d


def write_smplx(
    dirpath,
    gender: str = "neutral",
    fmt: str = "npz",
    layout: str = "1.1",
    seed: int = 0,
    kid_template: bool = False,
) -> Path:
    """Fake SMPL-X model (10475 vertices, 20908 faces, 55 joints, 486 features).

    ``layout="1.1"``: ``shapedirs`` (10475, 3, 400) = 300 shape + 100 expression components;
    ``"1.0"``: (10475, 3, 20) = 10 + 10. Keys: ``v_template``, ``f``, ``shapedirs``,
    ``posedirs``, ``J_regressor`` (55, 10475) dense, ``weights``, ``kintree_table``, hand PCA
    (``hands_components{l,r}``, ``hands_mean{l,r}``, ``hands_coeffs{l,r}``), landmarks
    (``lmk_faces_idx`` (51,), ``lmk_bary_coords`` (51, 3), ``dynamic_lmk_faces_idx`` (79, 17),
    ``dynamic_lmk_bary_coords`` (79, 17, 3)), ``vt`` (11313, 2), ``ft`` (20908, 3),
    ``joint2num``/``part2num`` (dicts; 0-d object arrays in the ``.npz``), and in the ``.npz``
    the stray ``allow_pickle`` entry the official archives carry. No ``J``, no chumpy.
    Name ``SMPLX_{GENDER}.{npz|pkl}``. Expression blend shapes move only the face.
    ``kid_template=True`` also writes ``smplx_kid_template.npy`` beside it.
    """
    g = _norm_gender(gender)
    _, d = _smplx_arrays(g, seed, layout)
    dirpath = Path(dirpath)
    dirpath.mkdir(parents=True, exist_ok=True)
    path = dirpath / f"SMPLX_{g.upper()}.{fmt}"
    keys = [
        "hands_meanr",
        "hands_meanl",
        "lmk_bary_coords",
        "vt",
        "posedirs",
        "part2num",
        "hands_coeffsr",
        "lmk_faces_idx",
        "J_regressor",
        "dynamic_lmk_faces_idx",
        "hands_componentsr",
        "shapedirs",
        "dynamic_lmk_bary_coords",
        "ft",
        "hands_componentsl",
        "joint2num",
        "v_template",
        "f",
        "hands_coeffsl",
        "kintree_table",
        "weights",
    ]
    if kid_template:
        write_kid_template(dirpath, "smplx", seed=seed, gender=g)
    if fmt == "npz":
        out = {}
        for k in keys:
            out[k] = _object0(d[k]) if isinstance(d[k], dict) else d[k]
            if k == "posedirs":
                out["allow_pickle"] = np.array(True)
        return _npz(path, out)
    if fmt == "pkl":
        return dump_legacy_pickle({k: d[k] for k in keys}, path)
    raise ValueError("fmt must be 'npz' or 'pkl'")


def write_kid_template(dirpath, model_type: str = "smplx", seed: int = 0, gender: str = "neutral") -> Path:
    """``{smpl|smplx}_kid_template.npy``: a (V, 3) float64 child-proportioned template.

    smplx uses it with ``age="kid"`` and ``kid_template_path=...``: it centres the template and
    appends ``kid - v_template`` as one extra shape direction. Works for SMPL, SMPL+H (use the
    ``smpl`` one) and SMPL-X.
    """
    g = _norm_gender(gender)
    if model_type == "smplx":
        v = _smplx_arrays(g, seed, "1.0")[1]["v_template"]
    elif model_type in ("smpl", "smplh"):
        v = _smpl_arrays(g, seed, 10)["v_template"]
        model_type = "smpl"
    else:
        raise ValueError("model_type must be 'smpl' or 'smplx'")
    rng = np.random.default_rng([seed, 4242])
    c = v.mean(axis=0)
    kid = (v - c) * np.array([0.62, 0.6, 0.62]) + c + rng.normal(0, 0.002, v.shape)
    dirpath = Path(dirpath)
    dirpath.mkdir(parents=True, exist_ok=True)
    path = dirpath / f"{model_type}_kid_template.npy"
    np.save(path, kid)
    return path


def write_smplx_kid_template(dirpath, seed: int = 0) -> Path:
    """``smplx_kid_template.npy`` (10475, 3); see :func:`write_kid_template`."""
    return write_kid_template(dirpath, "smplx", seed=seed)
