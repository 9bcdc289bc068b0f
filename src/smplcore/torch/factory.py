"""``create`` and ``build_layer``: smplx's factories, picking the class from the model type or the file."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from smplcore.family.specs import get_spec
from smplcore.torch.models import (
    FLAME,
    MANO,
    SMPL,
    SMPLH,
    SMPLX,
    FLAMELayer,
    MANOLayer,
    OpenModel,
    SMPLHLayer,
    SMPLLayer,
    SMPLXLayer,
)

_CLASSES = {
    "smpl": (SMPL, SMPLLayer),
    "smplh": (SMPLH, SMPLHLayer),
    "smplx": (SMPLX, SMPLXLayer),
    "mano": (MANO, MANOLayer),
    "flame": (FLAME, FLAMELayer),
    "open": (OpenModel, None),
}


def _resolve(model_path: str | Path | None, model_type: str | None, layer: bool, kwargs: dict) -> SMPL:
    from smplcore.io.model_files import load_model

    path = None if model_path is None or str(model_path) == "" else Path(model_path)
    if path is not None and path.is_file():
        data = load_model(path, model_type=model_type)
        model_type = data.model_type
        kwargs["data"] = data
    elif model_type is None:
        model_type = "smpl" if path is not None else "open"
    key = get_spec(model_type).model_type
    cls = _CLASSES[key][1 if layer else 0]
    if cls is None:
        raise ValueError(f"model_type: there is no Layer class for {model_type!r}")
    return cls(model_path if "data" not in kwargs else None, **kwargs)


def create(model_path: str | Path | None = None, model_type: str | None = None, **kwargs: Any) -> SMPL:
    """Build the module for a model file or folder, as ``smplx.create``.

    Parameters
    ----------
    model_path : a model file (its type is read from the file: official names such as
        ``basicModel_f_lbs_10_207_0_v1.0.0.pkl`` or ``generic_model.pkl`` work), or a folder laid out
        as smplx expects (``<folder>/<model_type>/SMPLX_NEUTRAL.npz``, or the files directly in it).
        None with ``model_type="open"`` loads the packaged open model.
    model_type : ``smpl`` (default for folders), ``smplh``, ``smplx``, ``mano``, ``flame`` or ``open``.
    **kwargs : the class's constructor keywords (``gender``, ``ext`` — smplx's default per class: ``npz``
        for SMPL-X, ``pkl`` otherwise; the other format is used when only it is there —, ``num_betas``,
        ``use_pca``, ..., and smplcore's ``kernel``, and ``dmpl_path``: a DMPL file whose blend shapes the
        forward's ``dmpls`` (B, n) drive).
    """
    return _resolve(model_path, model_type, False, kwargs)


def build_layer(model_path: str | Path | None = None, model_type: str | None = None, **kwargs: Any) -> SMPL:
    """Like :func:`create`, for the Layer classes (rotation-matrix inputs, no parameters)."""
    return _resolve(model_path, model_type, True, kwargs)
