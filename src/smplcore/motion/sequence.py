"""Motion sequences: AMASS-style parameter files as a typed :class:`Motion`.

AMASS stores one sequence per ``.npz``: ``poses`` (T, 3 J) axis-angle in the model's joint order
(SMPL+H: 156 values = root, 21 body joints, 15 + 15 hand joints; SMPL-X: 165 values = root, 21 body
joints, jaw, left eye, right eye, 15 + 15 hand joints), ``trans`` (T, 3), ``betas``, ``gender`` and
the frame rate (``mocap_framerate`` for SMPL+H, ``mocap_frame_rate`` for SMPL-X). Hand poses in AMASS
are absolute: evaluate them with ``flat_hand_mean=True`` and ``use_pca=False``.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from smplcore.errors import ModelFileError, ShapeError
from smplcore.family.specs import get_spec

if TYPE_CHECKING:
    from smplcore.motion.resample import ResamplePlan


class ShapeSpaceWarning(UserWarning):
    """A motion's betas, shape coefficients of its SMPL-family model, are fed to the open model, whose betas
    are coefficients of another shape space (they give another body)."""


_warned_shape_space: set[str] = set()


def warn_open_model_betas(motion_type: str, *, stacklevel: int = 2, key: str = "") -> None:
    """Warn once per process (per ``key``) that ``motion_type`` betas are fed to the open model."""
    if key in _warned_shape_space:
        return
    _warned_shape_space.add(key)
    name = get_spec(motion_type).display_name
    warnings.warn(
        f"betas: the motion's betas are {name} shape coefficients, but they drive the open model, whose betas "
        "mean something else (another shape space): the body will not have the captured shape. Use the "
        f"motion's own model to keep it (model_type={motion_type!r} with its model file), or drop the betas "
        "(num_betas=0)",
        ShapeSpaceWarning,
        stacklevel=stacklevel + 1,
    )


# Full-pose width (values per frame) of each model type.
# "open": the open model in SMPL's layout (a fit of it records it, so that its betas are read as its own)
POSE_WIDTH = {"open": 72, "smpl": 72, "smplh": 156, "smplx": 165, "mano": 48, "flame": 15}
_TYPE_BY_WIDTH = {v: k for k, v in POSE_WIDTH.items() if k != "open"}  # 72 values: SMPL


@dataclass(frozen=True)
class Motion:
    """A motion sequence of one body.

    Attributes
    ----------
    poses : (T, 3 J) axis-angle full pose per frame, in the joint order of ``model_type``.
    trans : (T, 3) root translation per frame (metres).
    betas : (S,) shape coefficients.
    fps : frames per second.
    model_type : ``smplh``, ``smplx``, ``smpl`` or ``open`` (the layout of ``poses``; ``open``: SMPL's layout,
        the open model's betas).
    gender : ``neutral``, ``male`` or ``female``.
    expression : (T, E) expression coefficients, or None.
    dmpls : (T, 8) soft-tissue coefficients (AMASS SMPL+H), kept but not used by the body models.
    source : the file it came from, or a description.
    """

    poses: np.ndarray
    trans: np.ndarray
    betas: np.ndarray
    fps: float
    model_type: str = "smplh"
    gender: str = "neutral"
    expression: np.ndarray | None = None
    dmpls: np.ndarray | None = None
    source: str = field(default="<memory>")

    def __post_init__(self) -> None:
        poses = np.asarray(self.poses)
        trans = np.asarray(self.trans)
        if poses.ndim != 2 or poses.shape[1] != POSE_WIDTH.get(self.model_type, -1):
            other = _TYPE_BY_WIDTH.get(poses.shape[1]) if poses.ndim == 2 else None
            hint = f"; {poses.shape[1]} values per frame are a {other!r} motion: model_type={other!r}" if other else ""
            raise ShapeError(
                f"poses: expected shape (T, {POSE_WIDTH.get(self.model_type, '3 J')}) for a "
                f"{self.model_type!r} motion, got {poses.shape}{hint}"
            )
        if trans.shape != (poses.shape[0], 3):
            raise ShapeError(f"trans: expected shape ({poses.shape[0]}, 3) to match poses, got {trans.shape}")
        if not np.isfinite(poses).all() or not np.isfinite(trans).all():
            bad = "poses" if not np.isfinite(poses).all() else "trans"
            raise ShapeError(f"{bad}: contains NaN or infinite values")
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"fps: expected a positive frame rate, got {self.fps}")

    @property
    def num_frames(self) -> int:
        return int(self.poses.shape[0])

    @property
    def duration(self) -> float:
        """Length in seconds."""
        return self.num_frames / self.fps

    def __len__(self) -> int:
        return self.num_frames

    def slice(self, start: int = 0, stop: int | None = None, step: int = 1) -> Motion:
        """Frames ``start:stop:step`` (the frame rate divides by ``step``)."""
        sl = np.s_[start:stop:step]
        return replace(
            self,
            poses=self.poses[sl],
            trans=self.trans[sl],
            fps=self.fps / step,
            expression=None if self.expression is None else self.expression[sl],
            dmpls=None if self.dmpls is None else self.dmpls[sl],
        )

    def resample(self, fps: float, method: str = "interp") -> Motion:
        """The motion at ``fps`` frames per second.

        ``method`` is ``"interp"`` (slerp of each joint's rotation, linear translation; exact
        target rate), ``"nearest"`` (nearest source frame; exact target rate) or ``"stride"``
        (every ``int(self.fps / fps)``-th frame, as HumanML3D; the rate becomes ``self.fps / step``).
        See :mod:`smplcore.motion.resample`.
        """
        from smplcore.motion import resample as rs

        p = rs.plan(self.num_frames, self.fps, fps, method)
        return self.take(p)

    def take(self, p: ResamplePlan) -> Motion:
        """The frames of a :class:`~smplcore.motion.resample.ResamplePlan` (see :meth:`resample`)."""
        from smplcore.motion import resample as rs

        def linear(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else rs.apply_linear(a, p)

        return replace(
            self,
            poses=rs.apply_rotations(self.poses, p),
            trans=rs.apply_linear(self.trans, p),
            fps=p.fps,
            expression=linear(self.expression),
            dmpls=linear(self.dmpls),
        )

    def model_params(
        self, model_type: str, joint_names: list[str] | None = None, num_betas: int | None = None
    ) -> dict[str, np.ndarray]:
        """Keyword arguments for a model of ``model_type``: its pose blocks, ``transl`` and ``betas``.

        The full pose is carried over joint by joint by name, so a SMPL+H motion drives SMPL, the
        open model or SMPL-X (joints the source lacks stay at zero rotation). The betas are carried
        over as they are: for the open model, whose betas mean something else, a
        :class:`ShapeSpaceWarning` says so (once per process) when they are not zero — those of them the model
        takes: ``num_betas``, the model's count (None: all; 0: none, no warning).
        """
        target = get_spec(model_type)
        used = np.asarray(self.betas)[:num_betas]
        if target.model_type == "open" and self.model_type != "open" and np.any(used != 0):
            warn_open_model_betas(self.model_type, stacklevel=2)
        names = list(joint_names or target.joint_names)
        source_names = list(get_spec(self.model_type).joint_names)
        frames = self.num_frames
        src = self.poses.reshape(frames, -1, 3)
        full = np.zeros((frames, len(names), 3), dtype=src.dtype)
        for j, name in enumerate(names):
            if name in source_names:
                full[:, j] = src[:, source_names.index(name)]
        params: dict[str, np.ndarray] = {}
        for block, (start, stop) in target.block_offsets().items():
            params[block] = full[:, start:stop].reshape(frames, -1)
        params["transl"] = self.trans
        params["betas"] = np.asarray(self.betas)[None]
        if self.expression is not None and target.has_expression:
            params["expression"] = self.expression
        return params


def _text(value: Any) -> str:
    value = np.asarray(value)
    item = value.item() if value.size == 1 else value
    if isinstance(item, bytes):
        return item.decode("utf-8", "replace")
    return str(item)


# The keys a motion is made of; an AMASS file holds more (e.g. SMPL-X files repeat the pose in
# ``root_orient``/``pose_body``/..., and hold marker data) that are not read.
_MOTION_KEYS = (
    "poses",
    "trans",
    "betas",
    "gender",
    "surface_model_type",
    "mocap_framerate",
    "mocap_frame_rate",
    "fps",
    "frame_rate",
    "expression",
    "dmpls",
)


def _read_motion_arrays(path: Path) -> dict[str, Any]:
    """The motion keys of an ``.npz`` (only those are inflated, within the loader's budgets), else the
    whole container; every failure is a ModelFileError naming the file."""
    from smplcore.io import LazyNpz, read_container

    container = read_container(path)
    if isinstance(container, LazyNpz):
        return {key: container[key] for key in container if key in _MOTION_KEYS}
    return dict(container)


FPS_KEYS = ("mocap_framerate", "mocap_frame_rate", "fps", "frame_rate")  # SMPL+H, SMPL-X, others


def load_motion(path: str | Path, *, default_fps: float | None = None) -> Motion:
    """Read an AMASS-style ``.npz`` (SMPL+H, SMPL-X or SMPL poses) without unpickling anything.

    ``default_fps`` is the frame rate of a file that states none; None (the default): such a file
    is refused (a guessed rate would silently change every resampled output).

    Raises
    ------
    ModelFileError
        naming the file and key: missing keys (the frame rate too), inconsistent shapes, NaNs,
        truncated archives.
    """
    path = Path(path)
    return motion_from_arrays(_read_motion_arrays(path), source=path, default_fps=default_fps)


def motion_from_arrays(
    raw: Mapping[str, Any], source: str | Path = "<memory>", *, default_fps: float | None = None
) -> Motion:
    """A :class:`Motion` from AMASS-style arrays (``poses`` (T, 3 J), ``trans`` (T, 3), ``betas``,
    ``gender``, a frame rate under one of :data:`FPS_KEYS`, optional ``surface_model_type``,
    ``expression``, ``dmpls``): the one AMASS reader, used by :func:`load_motion`.

    ``default_fps`` is the frame rate when none of :data:`FPS_KEYS` is there; None: a
    :class:`ModelFileError` naming ``source`` and the key, saying how to give the rate.
    """
    path = source
    for key in ("poses", "trans"):
        if key not in raw:
            raise ModelFileError(path, f"missing key; the file has {sorted(raw)}", key=key)
    poses = np.asarray(raw["poses"], dtype=np.float64)
    if poses.ndim != 2:
        raise ModelFileError(path, f"expected shape (T, 3 J), found {poses.shape}", key="poses")
    declared = _text(raw["surface_model_type"]).lower() if "surface_model_type" in raw else None
    model_type = declared or _TYPE_BY_WIDTH.get(poses.shape[1])
    if model_type not in POSE_WIDTH:
        raise ModelFileError(
            path,
            f"cannot tell the body model from {poses.shape[1]} pose values per frame "
            f"(expected one of {sorted(_TYPE_BY_WIDTH)})",
            key="poses",
        )
    fps_key = next((k for k in FPS_KEYS if k in raw), None)
    if fps_key is None and default_fps is None:
        raise ModelFileError(
            path,
            "missing the frame rate (mocap_framerate or mocap_frame_rate); add it to the file, or give "
            "the rate: load_motion(path, default_fps=...)",
            key="mocap_frame_rate" if model_type == "smplx" else "mocap_framerate",
        )
    gender = _text(raw.get("gender", "neutral")).strip().lower() or "neutral"
    betas = np.asarray(raw.get("betas", np.zeros(10)), dtype=np.float64)
    if betas.ndim == 2 and len(np.unique(betas, axis=0)) > 1:  # smplcore fit's multi-person output
        raise ModelFileError(
            path,
            f"holds {len(betas)} rows of shape coefficients (different people, e.g. a COCO file or an OpenPose "
            "sequence fitted with --person all); a motion is one person: take one person's rows (same image_id and "
            "person, or same track) and save them with that person's betas",
            key="betas",
        )
    betas = betas[0] if betas.ndim == 2 else betas.reshape(-1)
    if not np.isfinite(betas).all():
        raise ModelFileError(path, "contains NaN or infinite values", key="betas")
    optional = {k: np.asarray(raw[k], dtype=np.float64) for k in ("expression", "dmpls") if k in raw}
    for key, value in optional.items():
        if value.ndim != 2 or value.shape[0] != poses.shape[0]:
            raise ModelFileError(
                path, f"expected shape ({poses.shape[0]}, n) to match poses, found {value.shape}", key=key
            )
        if not np.isfinite(value).all():
            raise ModelFileError(path, "contains NaN or infinite values", key=key)
    if fps_key is None:
        fps = float(default_fps)  # type: ignore[arg-type]
    else:
        try:
            fps = float(np.asarray(raw[fps_key], dtype=np.float64).reshape(-1)[0])
        except (ValueError, TypeError, IndexError):
            raise ModelFileError(path, f"expected a frame rate, found {raw[fps_key]!r}", key=fps_key) from None
    try:
        return Motion(
            poses=poses,
            trans=np.asarray(raw["trans"], dtype=np.float64),
            betas=betas,
            fps=fps,
            model_type=model_type,
            gender=gender,
            source=str(path),
            **optional,
        )
    except (ShapeError, ValueError) as exc:
        culprit = str(exc).split(":")[0] if ":" in str(exc) else None
        raise ModelFileError(path, str(exc).split(": ", 1)[-1], key=culprit) from None


def save_motion(motion: Motion, path: str | Path) -> Path:
    """Write ``motion`` as an AMASS-style ``.npz`` (no pickles)."""
    path = Path(path)
    arrays: dict[str, Any] = {
        "poses": motion.poses,
        "trans": motion.trans,
        "betas": motion.betas,
        "gender": np.array(motion.gender),
        "surface_model_type": np.array(motion.model_type),
    }
    arrays["mocap_frame_rate" if motion.model_type == "smplx" else "mocap_framerate"] = np.array(motion.fps)
    if motion.expression is not None:
        arrays["expression"] = motion.expression
    if motion.dmpls is not None:
        arrays["dmpls"] = motion.dmpls
    np.savez(path, **arrays)
    return path
