"""What to compute for each sequence and how to store it: :class:`ProcessOptions`, recipes, output axes."""

from __future__ import annotations

import math
import re
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import SmplcoreError

DEFAULT_EXCLUDE = ("shape.npz",)  # AMASS's per-subject shape files: betas and gender, no motion


class ProcessError(SmplcoreError, ValueError):
    """The job cannot start: bad folders or settings, a locked or incompatible output folder."""


# --------------------------------------------------------------------------------------------------
# Settings


@dataclass(frozen=True)
class ProcessOptions:
    """What to compute for each sequence and how to store it.

    Attributes
    ----------
    model_path : model file or folder (see :func:`smplcore.io.locate.locate_model_file`); None
        for the packaged open model.
    model_type : model to evaluate; None: the type the motion file names (``open`` without a
        ``model_path``). Another type is driven joint by joint by name (e.g. SMPL+H data on ``open``).
    gender : ``file`` (the gendered model the file names), ``humanml3d`` (male if the file says
        male, else female) or a fixed ``neutral``/``male``/``female``.
    ext : model file extension to look for in a folder (None: npz, then pkl).
    num_betas : shape coefficients used (None: all the model file holds).
    fps : output frame rate (None: keep the source rate); ``resample`` is the method
        (``interp``, ``nearest`` or ``stride``, see :mod:`smplcore.motion.resample`).
    vertices : also write the mesh vertices (``.npz`` only).
    extra_joints : keep the model's extra vertex joints and landmarks after the skeleton joints.
    num_joints : keep only the first ``num_joints`` joints (HumanML3D uses 22).
    axes : output axes as three of ``x y z`` with optional signs, e.g. ``xzy`` (HumanML3D) or
        ``x,-z,y``; applied to joints and vertices.
    dtype : stored dtype, ``float32``, ``float16`` or ``float64`` (float64 also computes in float64).
    format : ``npz`` (joints, optional vertices and metadata) or ``npy`` (joints only, HumanML3D).
    compress : write compressed ``.npz``.
    backend : ``auto`` (NumPy, the fastest on a CPU), ``numpy`` or ``torch``.
    chunk : frames per forward call (None: the backend's best, see
        :class:`~smplcore.motion.models.Evaluator`).
    dmpl_path : a DMPL file (``dmpl.npz``); each sequence's ``dmpls`` (T, n) then drive its soft-tissue
        blend shapes (a sequence without them gets none).
    skinning : ``lbs`` (linear blend skinning, the default) or ``dqs`` (dual-quaternion skinning) for the
        vertices and the extra vertex joints (the skeleton joints are the same under both).
    """

    model_path: str | None = None
    model_type: str | None = None
    gender: str = "file"
    ext: str | None = None
    num_betas: int | None = None
    fps: float | None = None
    resample: str = "interp"
    vertices: bool = False
    extra_joints: bool = False
    num_joints: int | None = None
    axes: str = "xyz"
    dtype: str = "float32"
    format: str = "npz"
    compress: bool = False
    backend: str = "auto"
    chunk: int | None = None
    dmpl_path: str | None = None
    skinning: str = "lbs"

    def __post_init__(self) -> None:
        from smplcore.family.specs import get_spec
        from smplcore.motion.models import GENDER_RULES
        from smplcore.motion.resample import METHODS

        for name in ("model_path", "dmpl_path"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, str(Path(getattr(self, name)).expanduser().resolve()))
        if self.model_type is not None:
            object.__setattr__(self, "model_type", get_spec(self.model_type).model_type)
        if self.gender not in GENDER_RULES:
            raise ValueError(f"gender: expected one of {GENDER_RULES}, got {self.gender!r}")
        if self.resample not in METHODS:
            raise ValueError(f"resample: expected one of {METHODS}, got {self.resample!r}")
        if self.fps is not None:
            if not (math.isfinite(self.fps) and self.fps > 0):
                raise ValueError(f"fps: expected a positive frame rate, got {self.fps}")
            object.__setattr__(self, "fps", float(self.fps))
        if self.dtype not in ("float32", "float16", "float64"):
            raise ValueError(f"dtype: expected float32, float16 or float64, got {self.dtype!r}")
        if self.format not in ("npz", "npy"):
            raise ValueError(f"format: expected 'npz' or 'npy', got {self.format!r}")
        if self.format == "npy" and self.vertices:
            raise ValueError("format: 'npy' holds the joints only; use format 'npz' to write vertices")
        for name in ("num_betas", "num_joints"):
            value = getattr(self, name)
            if value is not None and (not isinstance(value, int) or value < (0 if name == "num_betas" else 1)):
                raise ValueError(f"{name}: expected a positive integer, got {value!r}")
        if self.chunk is not None and self.chunk < 1:
            raise ValueError(f"chunk: expected a positive number of frames, got {self.chunk}")
        parse_axes(self.axes)
        from smplcore.model import check_skinning

        check_skinning(self.skinning)

    @property
    def suffix(self) -> str:
        return "." + self.format

    def output_settings(self) -> dict[str, Any]:
        """The settings that decide the outputs' contents (kept in the manifest, checked on resume)."""
        out = asdict(self)
        for name in ("backend", "chunk"):  # how, not what
            out.pop(name)
        if out["dmpl_path"] is None:  # as before the option existed: older manifests still match
            out.pop("dmpl_path")
        if out["skinning"] == "lbs":  # the default, absent from manifests written before the option
            out.pop("skinning")
        return out


# A recipe is a set of option values; explicit options win over the recipe's.
RECIPES: dict[str, dict[str, Any]] = {
    # HumanML3D's raw_pose_processing: gendered SMPL+H (neutral files go to the female model), 10
    # betas, every int(fps / 20)-th frame, the 52 skeleton joints, y and z swapped, one .npy per file.
    "humanml3d": {
        "model_type": "smplh",
        "gender": "humanml3d",
        "num_betas": 10,
        "fps": 20.0,
        "resample": "stride",
        "axes": "xzy",
        "format": "npy",
        "extra_joints": False,
    },
}


def options_from_recipe(recipe: str | None, **explicit: Any) -> ProcessOptions:
    """:class:`ProcessOptions` from a recipe name (or None) and explicit values (None = not given)."""
    values: dict[str, Any] = {}
    if recipe is not None:
        if recipe not in RECIPES:
            raise ValueError(f"recipe: expected one of {sorted(RECIPES)}, got {recipe!r}")
        values.update(RECIPES[recipe])
    known = {f.name for f in fields(ProcessOptions)}
    unknown = set(explicit) - known
    if unknown:
        raise TypeError(f"unknown option(s) {sorted(unknown)}")
    values.update({k: v for k, v in explicit.items() if v is not None})
    return ProcessOptions(**values)


def parse_axes(axes: str) -> tuple[list[int], np.ndarray]:
    """``xzy`` / ``x,-z,y`` → (source column of each output axis, sign of each)."""
    tokens = re.findall(r"([+-]?)([xyz])", axes.lower())
    rest = re.sub(r"[+-]?[xyz]|[\s,]", "", axes.lower())
    cols = ["xyz".index(t[1]) for t in tokens]
    if rest or sorted(cols) != [0, 1, 2]:
        raise ValueError(
            f"axes: expected each of x, y, z once with optional signs (e.g. 'xzy', 'x,-z,y'), got {axes!r}"
        )
    return cols, np.array([-1.0 if t[0] == "-" else 1.0 for t in tokens])


def _apply_axes(points: np.ndarray, axes: str) -> np.ndarray:
    cols, signs = parse_axes(axes)
    if cols == [0, 1, 2] and (signs > 0).all():
        return points
    out = points[..., cols]
    return out * signs.astype(points.dtype) if (signs < 0).any() else out
