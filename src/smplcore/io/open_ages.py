"""The open model at any age from 1 to 90 years (``age=7.5``): ``open_ages.npz``, built by
``tools/build_open_ages.py`` from MakeHuman's CC0 age targets, calibrated to WHO stature-for-age medians.

The body at age ``a`` is the gender's template plus ``age_dirs @ c(a)``, ``c`` interpolated linearly between
the grid's ages; the shape basis is scaled by that body's stature over the adult template's, so betas keep
their relative effect. The joint regressor and skinning weights are the open model's own.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from smplcore.errors import ModelFileError
from smplcore.io.model_data import ModelData

__all__ = ["AGE_RANGE", "open_ages_path", "age_offsets", "at_age", "age_for_stature"]

DATA_DIR = Path(__file__).resolve().parents[1] / "data"
#: Ages (years) the age axis covers.
AGE_RANGE = (1.0, 90.0)


def open_ages_path() -> Path:
    path = DATA_DIR / "open_ages.npz"
    if not path.is_file():
        raise ModelFileError(path, "the open model's age axis is missing; rebuild it with tools/build_open_ages.py")
    return path


@lru_cache(maxsize=1)
def _tables() -> dict[str, np.ndarray]:
    with np.load(open_ages_path(), allow_pickle=False) as d:
        return {k: d[k] for k in d.files}


def _gender(data: ModelData) -> str:
    g = str(data.gender).lower()
    return g if g in ("male", "female") else "neutral"


def age_offsets(gender: str, years: float) -> tuple[np.ndarray, float]:
    """(V, 3) offset from the adult template of ``gender`` at ``years``, and that body's stature (m)."""
    t = _tables()
    ages = t["ages"].astype(np.float64)
    coeffs = t[f"coeffs_{gender}"].astype(np.float64)
    c = np.array([np.interp(years, ages, coeffs[:, k]) for k in range(coeffs.shape[1])])
    offset = t["age_dirs"].astype(np.float64) @ c
    return offset, float(np.interp(years, ages, t[f"stature_{gender}"].astype(np.float64)))


def at_age(data: ModelData, years: float, shapedirs: np.ndarray) -> tuple[ModelData, np.ndarray]:
    """The open model ``data`` at ``years`` of age, and ``shapedirs`` (V, 3, B) scaled to that body."""
    if data.model_type != "open":
        raise ValueError(
            f"age: a number of years needs the open model (model_type='open'), got a {data.model_type} model; "
            "use age='kid' with kid_template_path for SMPL / SMPL-X"
        )
    years = float(years)
    if not np.isfinite(years) or not AGE_RANGE[0] <= years <= AGE_RANGE[1]:
        raise ValueError(f"age: expected years in [{AGE_RANGE[0]:g}, {AGE_RANGE[1]:g}], 'adult' or 'kid', got {years}")
    offset, stature = age_offsets(_gender(data), years)
    template = np.asarray(data.v_template, dtype=np.float64)
    adult = float(np.ptp(template[:, 1]))
    return data.replace(v_template=template + offset), np.asarray(shapedirs) * (stature / adult)


def age_for_stature(stature: float, gender: str = "neutral") -> float:
    """The age (years, 1-19) at which the open model's mean body of ``gender`` has ``stature`` (m): the
    inverse of its growth curve (WHO medians), for starting a child's fit. Adult statures give 19."""
    g = str(gender).lower()
    if g not in ("neutral", "male", "female"):
        raise ValueError(f"gender: expected 'neutral', 'male' or 'female', got {gender!r}")
    s = float(stature)
    if not np.isfinite(s) or s <= 0:
        raise ValueError(f"stature: expected a positive length in metres, got {stature}")
    t = _tables()
    ages = t["ages"].astype(np.float64)
    grow = ages <= 19
    curve = np.maximum.accumulate(t[f"stature_{g}"].astype(np.float64)[grow])
    return float(np.interp(s, curve, ages[grow]))
