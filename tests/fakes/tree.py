"""A whole model tree laid out as smplx expects it, plus the official download names."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from . import meshes
from .body import write_smpl, write_smplh
from .mano_flame import write_flame, write_mano
from .smplx_model import write_kid_template, write_smplx


def _link(src: Path, dst: Path) -> Path:
    """Same bytes under another name (hard link when possible)."""
    dst.parent.mkdir(parents=True, exist_ok=True)
    if dst.exists():
        dst.unlink()
    try:
        os.link(src, dst)
    except OSError:
        shutil.copyfile(src, dst)
    return dst


def write_all(dirpath, seed: int = 0) -> dict:
    """Write a model tree usable as ``smplx.create(dirpath, model_type=...)``; return its paths.

    Layout (``*`` = loadable by smplx 0.1.28)::

        smpl/SMPL_NEUTRAL.pkl    * v1.1, 300 betas          key "smpl_neutral_pkl"
        smpl/SMPL_NEUTRAL.npz      same numbers, npz          "smpl_neutral_npz"
        smpl/SMPL_MALE.pkl       * v1.0, 10 betas           "smpl_male_pkl"
        smpl/SMPL_FEMALE.pkl     * v1.0, 10 betas           "smpl_female_pkl"
        smpl/smpl_kid_template.npy                           "smpl_kid_template"
        smplh/SMPLH_NEUTRAL.pkl  * merged, 10 betas          "smplh_neutral_pkl"
        smplh/SMPLH_FEMALE.npz   * AMASS + merged hand PCA, 16 betas   "smplh_female_npz"
        smplx/SMPLX_NEUTRAL.npz  * layout 1.1 (300 + 100)    "smplx_neutral_npz"
        smplx/SMPLX_NEUTRAL.pkl  * same numbers, pkl         "smplx_neutral_pkl"
        smplx/SMPLX_MALE.npz     * layout 1.0 (10 + 10)      "smplx_male_npz"
        smplx/smplx_kid_template.npy                         "smplx_kid_template"
        mano/MANO_RIGHT.pkl      *                           "mano_right_pkl"
        mano/MANO_LEFT.pkl       *                           "mano_left_pkl"
        flame/FLAME_NEUTRAL.pkl  *                           "flame_neutral_pkl"
        flame/flame_static_embedding.pkl                     "flame_static_embedding"
        flame/flame_dynamic_embedding.npy                    "flame_dynamic_embedding"
        official/smpl/basicModel_f_lbs_10_207_0_v1.0.0.pkl   (= SMPL_FEMALE.pkl)
                                                             "official_smpl_f_v1_0_pkl"
        official/smpl/basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl  (= SMPL_NEUTRAL.pkl)
                                                             "official_smpl_neutral_v1_1_pkl"
        official/smplh/SMPLH_male.pkl    raw MANO download: Ch, no hand PCA
                                                             "official_smplh_male_pkl"
        official/smplh_amass/neutral/model.npz  raw AMASS: 16 betas, no hand PCA
                                                             "official_smplh_amass_neutral_npz"
        official/flame/generic_model.pkl  (= FLAME_NEUTRAL.pkl)  "official_flame_generic_pkl"

    plus ``"root"``. Files with the same numbers are hard links (or copies).
    """
    with meshes.core_cache() as clear_cache:
        return _write_all(Path(dirpath), seed, clear_cache)


def _write_all(root: Path, seed: int, clear_cache) -> dict:
    p = {"root": root}
    smpl, smplh, smplx_d = root / "smpl", root / "smplh", root / "smplx"
    mano, flame, off = root / "mano", root / "flame", root / "official"
    p["smpl_neutral_pkl"] = write_smpl(smpl, "neutral", "1.1", "pkl", seed)
    p["smpl_neutral_npz"] = write_smpl(smpl, "neutral", "1.1", "npz", seed)
    p["smpl_male_pkl"] = write_smpl(smpl, "male", "1.0", "pkl", seed)
    p["smpl_female_pkl"] = write_smpl(smpl, "female", "1.0", "pkl", seed)
    p["smpl_kid_template"] = write_kid_template(smpl, "smpl", seed)
    p["official_smpl_f_v1_0_pkl"] = _link(p["smpl_female_pkl"], off / "smpl" / "basicModel_f_lbs_10_207_0_v1.0.0.pkl")
    p["official_smpl_neutral_v1_1_pkl"] = _link(
        p["smpl_neutral_pkl"], off / "smpl" / "basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl"
    )
    clear_cache()
    p["smplh_neutral_pkl"] = write_smplh(smplh, "neutral", "pkl", seed)
    p["smplh_female_npz"] = write_smplh(smplh, "female", "npz", seed, amass=True, hand_pca=True)
    p["official_smplh_male_pkl"] = write_smplh(off / "smplh", "male", "pkl", seed, hand_pca=False, official_name=True)
    p["official_smplh_amass_neutral_npz"] = write_smplh(
        off / "smplh_amass", "neutral", "npz", seed, amass=True, official_name=True
    )
    clear_cache()
    p["smplx_neutral_npz"] = write_smplx(smplx_d, "neutral", "npz", "1.1", seed)
    p["smplx_neutral_pkl"] = write_smplx(smplx_d, "neutral", "pkl", "1.1", seed)
    p["smplx_male_npz"] = write_smplx(smplx_d, "male", "npz", "1.0", seed)
    p["smplx_kid_template"] = write_kid_template(smplx_d, "smplx", seed)
    clear_cache()
    p["mano_right_pkl"] = write_mano(mano, "right", seed)
    p["mano_left_pkl"] = write_mano(mano, "left", seed)
    p["flame_neutral_pkl"] = write_flame(flame, "neutral", seed)
    p["flame_static_embedding"] = flame / "flame_static_embedding.pkl"
    p["flame_dynamic_embedding"] = flame / "flame_dynamic_embedding.npy"
    p["official_flame_generic_pkl"] = _link(p["flame_neutral_pkl"], off / "flame" / "generic_model.pkl")
    return p
