"""The packaged open model files: one per gender, as SMPL ships three (``neutral``, ``male``, ``female``).

All three are built by ``tools/build_open_model.py`` the same way, from adult populations sampled from
published anthropometric distributions (the neutral one: an even mix of men and women).
"""

from __future__ import annotations

from pathlib import Path

from smplcore.errors import ModelFileError

__all__ = ["OPEN_MODEL_FILES", "open_model_path"]

DATA_DIR = Path(__file__).resolve().parents[1] / "data"

#: gender -> file name in ``smplcore/data``.
OPEN_MODEL_FILES = {"neutral": "open_model.npz", "male": "open_model_male.npz", "female": "open_model_female.npz"}

_ALIASES = {"neutral": "neutral", "male": "male", "female": "female", "m": "male", "f": "female", "n": "neutral"}


def open_model_path(gender: str | None = "neutral") -> Path:
    """The packaged open model file of ``gender`` (``"neutral"`` (default, also for None), ``"male"``,
    ``"female"``; case-insensitive, ``"m"`` / ``"f"`` accepted).

    Raises
    ------
    ValueError
        for another gender (the message lists the choices).
    ModelFileError
        when the file is missing from the installation (it says how to rebuild it).
    """
    key = "neutral" if gender is None else _ALIASES.get(str(gender).strip().lower())
    if key is None:
        raise ValueError(f"gender: the open model comes as {sorted(OPEN_MODEL_FILES)}, got {gender!r}")
    path = DATA_DIR / OPEN_MODEL_FILES[key]
    if not path.is_file():
        raise ModelFileError(
            path, f"the packaged {key} open model is missing; rebuild it with `python tools/build_open_model.py`"
        )
    return path
