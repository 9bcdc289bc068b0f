"""MANO (right and left hands) and FLAME (head, with its landmark embeddings) files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.sparse as sp

from .meshes import _bary, _core, _expression, _hand_pca, _head_faces, _left_from_right_pca, _norm_gender
from .pickles import _ch, _save_legacy_npy_object, dump_legacy_pickle
from .sizes import _GENDER_SCALE, FLAME_FACES, FLAME_VERTS, MANO_FACES, MANO_VERTS
from .skeletons import _flame_skel, _mano_skel


def _mano_right(seed: int):
    skel = _mano_skel()
    _, mesh, d = _core("mano", "neutral", seed, MANO_VERTS, MANO_FACES, skel, 10, 0.005, 1e-3)
    d["shapedirs"] = d["shapedirs"].copy()
    d["shapedirs"][:, :, 0] = (mesh.v - mesh.v.mean(axis=0)) * 0.04  # overall hand size
    comps, mean, coeffs = _hand_pca(seed)
    d.update(hands_components=comps, hands_mean=mean, hands_coeffs=coeffs)
    return d


# R'[a, b] = s_a s_b R[a, b] for the mirror M = diag(-1, 1, 1)
_S = np.array([-1.0, 1.0, 1.0])
_POSE_FEATURE_MIRROR = np.outer(_S, _S).ravel()


def _mano_left(seed: int):
    r = _mano_right(seed)
    d = dict(r)
    d["v_template"] = r["v_template"] * _S
    d["J"] = r["J"] * _S
    d["f"] = r["f"][:, [0, 2, 1]].copy()
    n_feat = r["posedirs"].shape[2]
    feat = np.tile(_POSE_FEATURE_MIRROR, n_feat // 9)
    d["posedirs"] = r["posedirs"] * _S[None, :, None] * feat[None, None, :]
    # The official MANO_LEFT.pkl has shapedirs[:, 0, :] with the *same* sign as the right hand
    # (a true mirror would negate it); reproduce that known defect: y, z mirrored (unchanged),
    # x NOT negated.
    d["shapedirs"] = r["shapedirs"].copy()
    comps, mean, coeffs = _left_from_right_pca(r["hands_components"], r["hands_mean"], r["hands_coeffs"])
    d.update(hands_components=comps, hands_mean=mean, hands_coeffs=coeffs)
    return d


def write_mano(dirpath, side: str = "right", seed: int = 0) -> Path:
    """Fake ``MANO_RIGHT.pkl`` / ``MANO_LEFT.pkl`` (778 vertices, 16 joints, 135 features).

    Python 2 pickle with ``hands_components`` (45, 45) (rows = PCA directions scaled by their
    standard deviation, as in the real file), ``hands_mean`` (45,), ``hands_coeffs``
    (1554, 45), ``f`` (1538, 3), ``J_regressor`` csc (16, 778), ``kintree_table``, ``J``,
    ``bs_style``, ``bs_type``, ``weights``, ``posedirs`` (778, 3, 135), ``v_template``,
    ``shapedirs`` (778, 3, 10) chumpy ``Ch``. Joint order: wrist, index1-3, middle1-3,
    pinky1-3, ring1-3, thumb1-3.

    The left hand is the exact mirror (x -> -x) of the right one -- vertices, joints, reversed
    face winding, mirrored pose correctives and hand PCA (axis-angle (x, y, z) -> (x, -y, -z))
    -- except ``shapedirs[:, 0, :]``, which keeps the right hand's sign, reproducing the known
    defect of the official ``MANO_LEFT.pkl``.
    """
    side = side.lower()
    if side not in ("right", "left"):
        raise ValueError("side must be 'right' or 'left'")
    d = _mano_right(seed) if side == "right" else _mano_left(seed)
    dirpath = Path(dirpath)
    dirpath.mkdir(parents=True, exist_ok=True)
    out = {
        "hands_components": d["hands_components"],
        "f": d["f"],
        "J_regressor": sp.csc_matrix(d["J_regressor"]),
        "kintree_table": d["kintree_table"],
        "J": d["J"],
        "bs_style": "lbs",
        "hands_coeffs": d["hands_coeffs"],
        "weights": d["weights"],
        "posedirs": d["posedirs"],
        "hands_mean": d["hands_mean"],
        "v_template": d["v_template"],
        "shapedirs": _ch(d["shapedirs"]),
        "bs_type": "lrotmin",
    }
    return dump_legacy_pickle(out, dirpath / f"MANO_{side.upper()}.pkl")


def _flame_arrays(gender: str, seed: int):
    g = _norm_gender(gender)
    skel = _flame_skel(_GENDER_SCALE[g])
    rng, mesh, d = _core("flame", g, seed, FLAME_VERTS, FLAME_FACES, skel, 300, 0.004, 1e-3)
    expr = _expression(rng, mesh, skel, 100, 3e-3)
    d["shapedirs"] = np.concatenate([d["shapedirs"], expr], axis=2)
    front = _head_faces(mesh, skel, d["f"], front=True)
    allhead = _head_faces(mesh, skel, d["f"], front=False)
    lrng = np.random.default_rng([seed, 5151])
    lmk = {
        "static": (lrng.choice(front, 51, replace=False).astype(np.uint32), _bary(lrng, 51)),
        "dynamic": (lrng.choice(allhead, (79, 17)).astype(np.uint32), _bary(lrng, (79, 17))),
    }
    return d, lmk


def write_flame_landmarks(dirpath, seed: int = 0) -> tuple[Path, Path]:
    """``flame_static_embedding.pkl`` and ``flame_dynamic_embedding.npy`` (what smplx reads).

    Static: Python 2 pickle of ``{"lmk_face_idx": (51,) uint32, "lmk_b_coords": (51, 3)}``.
    Dynamic: a ``.npy`` holding a 0-d object array with the dict ``{"lmk_face_idx": (79, 17)
    uint32, "lmk_b_coords": (79, 17, 3)}`` (needs ``allow_pickle=True, encoding="latin1"``).
    Face indices refer to the FLAME mesh of the same seed (any gender: same topology).
    """
    _, lmk = _flame_arrays("neutral", seed)
    dirpath = Path(dirpath)
    dirpath.mkdir(parents=True, exist_ok=True)
    static = dump_legacy_pickle(
        {"lmk_face_idx": lmk["static"][0], "lmk_b_coords": lmk["static"][1]},
        dirpath / "flame_static_embedding.pkl",
    )
    dynamic = _save_legacy_npy_object(
        {"lmk_face_idx": lmk["dynamic"][0], "lmk_b_coords": lmk["dynamic"][1]},
        dirpath / "flame_dynamic_embedding.npy",
    )
    return static, dynamic


def write_flame(
    dirpath, gender: str = "neutral", seed: int = 0, official_name: bool = False, landmarks: bool = True
) -> Path:
    """Fake FLAME 2020 model (5023 vertices, 9976 faces, 5 joints, 36 features).

    Joints: global (root), neck, jaw, left eye, right eye (parents -1, 0, 1, 1, 1), matching
    smplx's pose order [global, neck, jaw, leye, reye]. Python 2 pickle with ``f``,
    ``v_template``, ``shapedirs`` (5023, 3, 400) chumpy ``Ch`` (300 shape + 100 expression,
    expressions move only the face), ``posedirs`` (5023, 3, 36), ``J_regressor`` csc (5, 5023),
    ``kintree_table``, ``J``, ``weights``, ``bs_style``, ``bs_type``.

    smplx 0.1.28 reads ``<dir>/FLAME_{GENDER}.pkl`` (gender upper-cased, default NEUTRAL);
    the download names them ``generic_model.pkl`` / ``male_model.pkl`` / ``female_model.pkl``
    (``official_name=True``; gender ``"generic"`` == ``"neutral"``). With ``landmarks`` the two
    embedding files smplx also needs are written beside it (:func:`write_flame_landmarks`).
    """
    g = _norm_gender(gender)
    d, _ = _flame_arrays(g, seed)
    dirpath = Path(dirpath)
    dirpath.mkdir(parents=True, exist_ok=True)
    if official_name:
        name = {"neutral": "generic", "male": "male", "female": "female"}[g] + "_model.pkl"
    else:
        name = f"FLAME_{g.upper()}.pkl"
    out = {
        "f": d["f"],
        "v_template": d["v_template"],
        "shapedirs": _ch(d["shapedirs"]),
        "posedirs": d["posedirs"],
        "J_regressor": sp.csc_matrix(d["J_regressor"]),
        "kintree_table": d["kintree_table"],
        "J": d["J"],
        "weights": d["weights"],
        "bs_style": "lbs",
        "bs_type": "lrotmin",
    }
    path = dump_legacy_pickle(out, dirpath / name)
    if landmarks:
        write_flame_landmarks(dirpath, seed)
    return path
