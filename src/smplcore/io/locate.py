"""Finding the model file that ``create(model_path, model_type=..., gender=..., ext=...)`` means."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

from smplcore.errors import ModelFileError
from smplcore.family.specs import get_spec
from smplcore.io.open_model import open_model_path  # noqa: E402

OPEN_MODEL_PATH = open_model_path("neutral")


def _outside_smplcore() -> int:
    """The ``stacklevel`` at which a warning issued by the caller points at the first frame outside smplcore."""
    frame, level = sys._getframe(2), 2
    while frame is not None and str(frame.f_globals.get("__name__", "")).split(".")[0] == "smplcore":
        frame, level = frame.f_back, level + 1
    return level


def default_ext(model_type: str) -> str:
    """smplx's default file format per model: ``npz`` for SMPL-X, ``pkl`` for the others."""
    return "npz" if get_spec(model_type).model_type == "smplx" else "pkl"


def locate_model_file(
    model_path: str | Path | None,
    model_type: str | None = None,
    *,
    gender: str = "neutral",
    ext: str | None = None,
    is_rhand: bool = True,
) -> Path:
    """The file to load.

    ``model_path`` may be a file (used as is), or a folder holding the official file names either
    directly or in a sub-folder named after the model type (``models/smplx/SMPLX_NEUTRAL.npz``), as
    smplx lays them out. ``ext`` (default: :func:`default_ext`) is honoured for every model type; when
    that file is missing and the same model is there in the other format (``.pkl`` / ``.npz``), that one
    is used. ``model_type="open"`` without a path gives the packaged open model.
    """
    if model_path is None or str(model_path) == "":
        if model_type is not None and get_spec(model_type).model_type == "open":
            return open_model_path(gender)
        raise ValueError(
            "model_path: a model file or folder is needed (or model_type='open' for the packaged open model)"
        )
    path = Path(model_path).expanduser()
    if path.exists() and not path.is_dir():
        return path  # a file (or a FIFO, device, ...: the loader refuses those clearly)
    if not path.exists():
        raise ModelFileError(path, "no such file or folder")
    if model_type is None:
        raise ValueError(f"model_type: {path} is a folder; say which model type to load from it")
    spec = get_spec(model_type)
    if spec.model_type == "open":
        warnings.warn(
            f"model_path: {str(path)!r} is a folder, which model_type='open' ignores: the packaged open model is "
            "used; pass no model_path (or the path of an open-model .npz file) to silence this",
            stacklevel=_outside_smplcore(),
        )
        return open_model_path(gender)
    folder = path / spec.model_type if (path / spec.model_type).is_dir() else path
    ext = (ext or default_ext(spec.model_type)).lstrip(".").lower()
    if ext not in ("pkl", "npz"):
        raise ValueError(f"ext: expected 'pkl' or 'npz', got {ext!r}")
    stem = spec.file_stem.format(GENDER=str(gender).upper(), SIDE="RIGHT" if is_rhand else "LEFT")
    other = "npz" if ext == "pkl" else "pkl"
    # the requested format first, then the same model in the other format (smplx's SMPL always reads .pkl,
    # so code written for it passes any ext)
    candidates = [folder / f"{stem}.{ext}", folder / f"{stem}.{other}"]
    if spec.model_type == "flame":
        candidates += [folder / f"generic_model.{ext}", folder / f"generic_model.{other}"]
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    present = sorted(p.name for p in folder.iterdir() if p.suffix in (".pkl", ".npz"))
    raise ModelFileError(
        candidates[0],
        f"not found (model_type={spec.model_type!r}, gender={gender!r}, "
        f"ext={ext!r}); model files in {folder}: {present or 'none'}",
    )


def read_model(
    model_path: str | Path | None,
    model_type: str | None = None,
    *,
    gender: str = "neutral",
    ext: str | None = None,
    is_rhand: bool = True,
):
    """Locate and load a model: :func:`locate_model_file` then :func:`smplcore.io.load_model`.

    For a folder, ``gender`` (and for MANO ``is_rhand``) choose the file and are recorded; for a
    file, they are taken from its name where it states them.
    """
    from smplcore.io.model_files import load_model

    path = locate_model_file(model_path, model_type, gender=gender, ext=ext, is_rhand=is_rhand)
    given_file = model_path is not None and str(model_path) != "" and Path(model_path).is_file()
    if model_type is not None and get_spec(model_type).model_type == "mano" and not given_file:
        gender = "right" if is_rhand else "left"
    return load_model(path, model_type=model_type, gender=None if given_file else gender)
