"""SMPL and SMPL+H files (pickle and npz flavours) and SMPL's separate UV ``.obj``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.sparse as sp

from .meshes import _core, _hand_pca, _left_from_right_pca, _norm_gender, _regressor, _seam_uvs
from .pickles import _ch, _npz, dump_legacy_pickle
from .sizes import _GENDER_SCALE, SMPL_FACES, SMPL_UVS, SMPL_VERTS
from .skeletons import _smpl_skel, _smplh_skel


def _smpl_arrays(gender: str, seed: int, n_shape: int):
    g = _norm_gender(gender)
    skel = _smpl_skel(_GENDER_SCALE[g])
    rng, mesh, d = _core("smpl", g, seed, SMPL_VERTS, SMPL_FACES, skel, 300, 0.02, 2e-3)
    d["shapedirs"] = np.ascontiguousarray(d["shapedirs"][:, :, :n_shape])
    w_prior = d["weights"] * rng.uniform(0.8, 1.2, d["weights"].shape)
    w_prior /= w_prior.sum(axis=1, keepdims=True)
    d["weights_prior"] = w_prior
    d["J_regressor_prior"] = _regressor(rng, mesh.v, skel.pos)
    d["vert_sym_idxs"] = mesh.sym.astype(np.int64)
    d["bs_style"] = "lbs"
    d["bs_type"] = "lrotmin"
    return d


def write_smpl(
    dirpath,
    gender: str = "neutral",
    version: str = "1.1",
    fmt: str = "pkl",
    seed: int = 0,
    official_name: bool = False,
) -> Path:
    """Fake SMPL model (6890 vertices, 24 joints, 207 pose-corrective features).

    ``version="1.0"``: 10 shape components, ``"1.1"``: 300. ``fmt="pkl"``: the official
    Python-2 pickle (``shapedirs`` a chumpy ``Ch``, ``J_regressor``/``J_regressor_prior``
    ``scipy.sparse.csc_matrix``, ``pose_training_info`` a dict, ``bs_style``/``bs_type`` str).
    ``fmt="npz"``: the same arrays, chumpy-free, regressors dense, no ``pose_training_info``
    (loads without ``allow_pickle``).

    File name: ``SMPL_{GENDER}.{pkl|npz}`` (what smplx looks for), or with ``official_name``
    the download's name: v1.0 ``basicModel_f_lbs_10_207_0_v1.0.0.pkl`` /
    ``basicmodel_m_lbs_10_207_0_v1.0.0.pkl`` / ``basicModel_neutral_lbs_10_207_0_v1.0.0.pkl``
    (the neutral one ships with SMPLify), v1.1 ``basicModel_f_lbs_10_207_0_v1.1.0.pkl`` /
    ``basicmodel_m_lbs_10_207_0_v1.1.0.pkl`` / ``basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl``
    (the mixed case is as distributed, as far as known: readers should match names
    case-insensitively).
    """
    if version not in ("1.0", "1.1"):
        raise ValueError("version must be '1.0' or '1.1'")
    g = _norm_gender(gender)
    d = _smpl_arrays(g, seed, 10 if version == "1.0" else 300)
    dirpath = Path(dirpath)
    dirpath.mkdir(parents=True, exist_ok=True)
    if official_name:
        letter = {"female": "f", "male": "m", "neutral": "neutral"}[g]
        stem = {
            "1.0": {"f": "basicModel", "m": "basicmodel", "neutral": "basicModel"},
            "1.1": {"f": "basicModel", "m": "basicmodel", "neutral": "basicmodel"},
        }[version][letter]
        vtag = "v1.0.0" if version == "1.0" else "v1.1.0"
        name = f"{stem}_{letter}_lbs_10_207_0_{vtag}.{fmt}"
    else:
        name = f"SMPL_{g.upper()}.{fmt}"
    path = dirpath / name
    if fmt == "pkl":
        out = {
            "J_regressor_prior": sp.csc_matrix(d["J_regressor_prior"]),
            "f": d["f"],
            "J_regressor": sp.csc_matrix(d["J_regressor"]),
            "kintree_table": d["kintree_table"],
            "J": d["J"],
            "weights_prior": d["weights_prior"],
            "weights": d["weights"],
            "vert_sym_idxs": d["vert_sym_idxs"],
            "posedirs": d["posedirs"],
            "pose_training_info": {"rot_type": "lrotmin", "n_subjects": 40, "n_poses": 1786, "lambda": 0.01},
            "bs_style": "lbs",
            "v_template": d["v_template"],
            "shapedirs": _ch(d["shapedirs"]),
            "bs_type": "lrotmin",
        }
        return dump_legacy_pickle(out, path)
    if fmt == "npz":
        keys = [
            "J_regressor_prior",
            "f",
            "J_regressor",
            "kintree_table",
            "J",
            "weights_prior",
            "weights",
            "vert_sym_idxs",
            "posedirs",
            "bs_style",
            "v_template",
            "shapedirs",
            "bs_type",
        ]
        return _npz(
            path,
            {k: (np.asarray(d[k]) if k not in ("bs_style", "bs_type") else np.array(d[k])) for k in keys},
        )
    raise ValueError("fmt must be 'pkl' or 'npz'")


def _smplh_arrays(gender: str, seed: int, n_shape: int):
    g = _norm_gender(gender)
    skel = _smplh_skel(_GENDER_SCALE[g])
    rng, mesh, d = _core("smplh", g, seed, SMPL_VERTS, SMPL_FACES, skel, 16, 0.02, 2e-3)
    d["shapedirs"] = np.ascontiguousarray(d["shapedirs"][:, :, :n_shape])
    w_prior = d["weights"] * rng.uniform(0.8, 1.2, d["weights"].shape)
    d["weights_prior"] = w_prior / w_prior.sum(axis=1, keepdims=True)
    d["J_regressor_prior"] = _regressor(rng, mesh.v, skel.pos)
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
    return d


_HAND_KEYS = (
    "hands_componentsl",
    "hands_componentsr",
    "hands_coeffsl",
    "hands_coeffsr",
    "hands_meanl",
    "hands_meanr",
)


def write_smplh(
    dirpath,
    gender: str = "neutral",
    fmt: str = "pkl",
    seed: int = 0,
    amass: bool | None = None,
    hand_pca: bool | None = None,
    official_name: bool = False,
) -> Path:
    """Fake SMPL+H model (6890 vertices, 52 joints = 22 body + 2 x 15 fingers, 459 features).

    Three real-world flavours:

    * ``fmt="pkl"`` (default ``hand_pca=True``): the file smplx expects after its
      ``tools/merge_smplh_mano.py``: the MANO download's SMPL+H pickle with MANO's hand PCA
      added as ``hands_components{l,r}`` (45, 45), ``hands_mean{l,r}`` (45,),
      ``hands_coeffs{l,r}`` (1554, 45); chumpy converted to ndarray, ``J_regressor`` still
      ``csc_matrix``; 10 shape components; written by Python 3 (protocol 4, legacy module names).
    * ``fmt="pkl", hand_pca=False``: the raw MANO-download file (``mano_v1_2/models``): Python 2
      pickle, ``shapedirs`` a chumpy ``Ch``, no ``hands_*`` keys -- smplx cannot load it.
      ``official_name`` gives its real name ``SMPLH_{female|male}.pkl`` (lower case).
    * ``fmt="npz"`` / ``amass=True``: the "Extended SMPL+H model" used by AMASS: 16 shape
      components, dense regressors, **no** ``hands_*`` keys by default (so smplx fails with
      ``'Struct' object has no attribute 'hands_componentsl'``, as with the real file); with
      ``hand_pca=True`` the hand PCA is merged in (loadable by smplx with ``ext="npz"``).
      ``official_name`` writes the AMASS layout ``{gender}/model.npz`` below ``dirpath``.

    Without ``official_name`` the name is ``SMPLH_{GENDER}.{ext}``. The hand PCA equals the one
    written by :func:`write_mano` for the same seed (left = mirrored right).
    """
    if amass is None:
        amass = fmt == "npz"
    if amass and fmt != "npz":
        raise ValueError("the AMASS SMPL+H model is an .npz")
    if hand_pca is None:
        hand_pca = not amass
    g = _norm_gender(gender)
    d = _smplh_arrays(g, seed, 16 if amass else 10)
    dirpath = Path(dirpath)
    if official_name:
        if amass:
            path = dirpath / g / "model.npz"
        else:
            path = dirpath / f"SMPLH_{g}.pkl"
    else:
        path = dirpath / f"SMPLH_{g.upper()}.{fmt}"
    path.parent.mkdir(parents=True, exist_ok=True)
    base = {
        "J_regressor_prior": d["J_regressor_prior"],
        "f": d["f"],
        "J_regressor": d["J_regressor"],
        "kintree_table": d["kintree_table"],
        "J": d["J"],
        "weights_prior": d["weights_prior"],
        "weights": d["weights"],
        "posedirs": d["posedirs"],
        "bs_style": "lbs",
        "v_template": d["v_template"],
        "shapedirs": d["shapedirs"],
        "bs_type": "lrotmin",
    }
    if hand_pca:
        base.update({k: d[k] for k in _HAND_KEYS})
    if fmt == "npz":
        return _npz(path, {k: np.asarray(v) for k, v in base.items()})
    if fmt != "pkl":
        raise ValueError("fmt must be 'pkl' or 'npz'")
    base["J_regressor_prior"] = sp.csc_matrix(base["J_regressor_prior"])
    base["J_regressor"] = sp.csc_matrix(base["J_regressor"])
    if hand_pca:  # merged by a Python 3 script: plain ndarrays, default protocol
        return dump_legacy_pickle(base, path, protocol=4, py2_strings=False)
    base["shapedirs"] = _ch(base["shapedirs"])
    return dump_legacy_pickle(base, path)


def write_smpl_uv_obj(dirpath, seed: int = 0, name: str = "smpl_uv.obj", shuffle_faces: bool = False) -> Path:
    """Fake of the UV map SMPL distributes as a separate Wavefront ``.obj``: the neutral SMPL
    template (6890 ``v`` lines), 7576 ``vt`` lines (seam duplicates, see :func:`_seam_uvs`) and the
    13776 SMPL faces as ``f v/vt v/vt v/vt`` (1-based), in the model's face order unless
    ``shuffle_faces`` (then the faces are permuted and their corners rotated, to test matching).

    The real file's vt count (7576) and face order are taken to be these; its other lines
    (``vn``, ``s``, comments) are not reproduced."""
    d = _smpl_arrays("neutral", seed, 10)
    rng = np.random.default_rng([seed, 7576])
    f = d["f"].astype(np.int64)
    vt, ft = _seam_uvs(rng, d["v_template"], f, SMPL_UVS)
    ft = ft.astype(np.int64)
    if shuffle_faces:
        order = rng.permutation(f.shape[0])
        shift = rng.integers(0, 3, f.shape[0])
        cols = (shift[:, None] + np.arange(3)[None]) % 3
        f = np.take_along_axis(f[order], cols, axis=1)
        ft = np.take_along_axis(ft[order], cols, axis=1)
    lines = ["# fake SMPL UV map (tests/fakes.py)"]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in d["v_template"]]
    lines += [f"vt {u:.6f} {w:.6f}" for u, w in vt]
    lines += [f"f {a + 1}/{ta + 1} {b + 1}/{tb + 1} {c + 1}/{tc + 1}" for (a, b, c), (ta, tb, tc) in zip(f, ft)]
    dirpath = Path(dirpath)
    dirpath.mkdir(parents=True, exist_ok=True)
    path = dirpath / name
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
