"""``.smpl`` files (Meshcapade's open smplcodec format) and the ``.npz`` layout the SMPL-X Blender add-ons import.

**.smpl** -- a flat ``.npz`` (zip of ``.npy``, read with ``allow_pickle=False``) of camelCase keys, each an
``int32`` or ``float32`` array:

=======================  ============  =====================================================================
key                      dtype, shape  meaning
=======================  ============  =====================================================================
``codecVersion``         int32 ()      format major version (2; files without it are version 1)
``smplVersion``          int32 ()      0 SMPL, 1 SMPL+H, 2 SMPL-X, 3 SUPR, 4 SMPL++, 5 SKEL, 6 SMIL, 7 SMPL-XS
``gender``               int32 ()      0 neutral, 1 male, 2 female
``shapeParameters``      float32 (S,)  betas
``frameCount``           int32 ()      T (absent: a body shape without motion)
``frameRate``            float32 ()    frames per second (required when T > 1)
``bodyTranslation``      float32 (T,3) root translation, metres
``bodyPose``             float32       axis-angle from the pelvis: (T, 24, 3) SMPL; (T, 22, 3) SMPL+H / SMPL-X
``headPose``             float32       (T, 3, 3) jaw, left eye, right eye (SMPL-X)
``leftHandPose``         float32       (T, 15, 3) left index1 ... thumb3 (SMPL+H, SMPL-X)
``rightHandPose``        float32       (T, 15, 3)
``expressionParameters`` float32 (T,E) expression coefficients (SMPL-X)
``vertexOffsets``        float32 (V,3) per-vertex offsets outside the shape space
=======================  ============  =====================================================================

Concatenated in that order (body, head, left hand, right hand) the pose blocks are the AMASS full pose of
the model (SMPL 72, SMPL+H 156, SMPL-X 165 values per frame), so AMASS <-> ``.smpl`` is a reshape
(:func:`amass_to_smpl`, :func:`smpl_to_amass`). Poses are absolute joint rotations, as AMASS stores them
(hands relative to a flat hand).

**Blender add-on npz** -- the SMPL-X Blender add-on's *Add Animation* reads an AMASS-style ``.npz``:
``poses`` (T, 165) SMPL-X or (T, 156) SMPL+H axis-angle, ``trans`` (T, 3), ``betas`` (S,), ``gender``
(a string) and ``mocap_frame_rate`` (``mocap_framerate`` is also read). Its *anim_format* option says how
the data is oriented: ``AMASS`` for Z-up data (as AMASS ships it: the add-on turns the root by -90 deg about
X), ``SMPL-X`` for the model's own Y-up frame. :func:`save_blender_npz` writes either
(``up="y"`` -> import with ``SMPL-X``, ``up="z"`` -> ``AMASS``).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ModelFileError, ShapeError, warn

__all__ = [
    "SMPL_VERSIONS",
    "SmplFile",
    "amass_to_smpl",
    "load_blender_npz",
    "read_smpl",
    "save_blender_npz",
    "save_smpl",
    "smpl_to_amass",
    "write_smpl",
]

#: ``smplVersion`` code -> model name (the index is the code)
SMPL_VERSIONS = ("smpl", "smplh", "smplx", "supr", "smplpp", "skel", "smil", "smplxs")
GENDERS = ("neutral", "male", "female")
CODEC_VERSION = 2

#: pose blocks of each model that has an AMASS full pose: (field, joints)
_BLOCKS: dict[str, tuple[tuple[str, int], ...]] = {
    "smpl": (("body_pose", 24),),
    "smplh": (("body_pose", 22), ("left_hand_pose", 15), ("right_hand_pose", 15)),
    "smplx": (("body_pose", 22), ("head_pose", 3), ("left_hand_pose", 15), ("right_hand_pose", 15)),
}
_BLOCKS["smil"] = _BLOCKS["smpl"]
_BLOCKS["supr"] = _BLOCKS["smplxs"] = _BLOCKS["smplx"]

_KEYS = {  # file key -> field
    "codecVersion": "codec_version",
    "smplVersion": "model_type",
    "gender": "gender",
    "shapeParameters": "betas",
    "frameCount": "frame_count",
    "frameRate": "fps",
    "bodyTranslation": "transl",
    "bodyPose": "body_pose",
    "headPose": "head_pose",
    "leftHandPose": "left_hand_pose",
    "rightHandPose": "right_hand_pose",
    "expressionParameters": "expression",
    "vertexOffsets": "vertex_offsets",
}
_INT_KEYS = ("codecVersion", "smplVersion", "gender", "frameCount")
_POSE_FIELDS = ("body_pose", "head_pose", "left_hand_pose", "right_hand_pose")


@dataclass(frozen=True)
class SmplFile:
    """The content of a ``.smpl`` file (see the module docs), arrays float32.

    Attributes
    ----------
    model_type : ``smpl``, ``smplh``, ``smplx`` (or another :data:`SMPL_VERSIONS` name).
    gender : ``neutral``, ``male`` or ``female``.
    betas : (S,) shape coefficients, or None.
    frame_count : T, or None for a shape without motion.
    fps : frames per second, or None.
    transl : (T, 3) root translation, or None.
    body_pose, head_pose, left_hand_pose, right_hand_pose : (T, n, 3) axis-angle blocks, or None.
    expression : (T, E), or None.
    vertex_offsets : (V, 3), or None.
    codec_version : the format version.
    source : the file it was read from.
    """

    model_type: str = "smplx"
    gender: str = "neutral"
    betas: np.ndarray | None = None
    frame_count: int | None = None
    fps: float | None = None
    transl: np.ndarray | None = None
    body_pose: np.ndarray | None = None
    head_pose: np.ndarray | None = None
    left_hand_pose: np.ndarray | None = None
    right_hand_pose: np.ndarray | None = None
    expression: np.ndarray | None = None
    vertex_offsets: np.ndarray | None = None
    codec_version: int = CODEC_VERSION
    source: str = field(default="<memory>", compare=False)

    def __post_init__(self) -> None:
        where = self.source
        if self.model_type not in SMPL_VERSIONS:
            raise ModelFileError(where, f"expected one of {SMPL_VERSIONS}, got {self.model_type!r}", key="smplVersion")
        if self.gender not in GENDERS:
            raise ModelFileError(where, f"expected one of {GENDERS}, got {self.gender!r}", key="gender")
        frames = self.frame_count
        if frames is None:
            present = [f for f in ("transl", *_POSE_FIELDS, "expression") if getattr(self, f) is not None]
            if present:
                raise ModelFileError(where, f"{present} given without a frame count", key="frameCount")
            return
        if frames < 1:
            raise ModelFileError(where, f"expected a positive frame count, got {frames}", key="frameCount")
        if frames > 1 and (self.fps is None or not np.isfinite(self.fps) or self.fps <= 0):
            raise ModelFileError(where, f"{frames} frames need a positive frame rate, got {self.fps}", key="frameRate")
        expected: dict[str, tuple[int, ...]] = {"transl": (frames, 3)}
        expected.update({name: (frames, n, 3) for name, n in _BLOCKS.get(self.model_type, ())})
        for name, shape in expected.items():
            value = getattr(self, name)
            if value is not None and value.shape != shape:
                key = next(k for k, f in _KEYS.items() if f == name)
                raise ModelFileError(where, f"expected shape {shape}, found {value.shape}", key=key)
        if self.expression is not None and (self.expression.ndim != 2 or self.expression.shape[0] != frames):
            raise ModelFileError(
                where, f"expected shape ({frames}, E), found {self.expression.shape}", key="expressionParameters"
            )

    @property
    def num_frames(self) -> int:
        return self.frame_count or 1

    def full_pose(self) -> np.ndarray:
        """(T, 3 J) the AMASS full pose (blocks absent from the file are zeros); T = 1 without motion."""
        if self.model_type not in _BLOCKS:
            raise ValueError(
                f"{self.source}: a {self.model_type} file has no SMPL-family full pose "
                f"(known: {', '.join(sorted(_BLOCKS))})"
            )
        frames = self.num_frames
        parts = [
            np.zeros((frames, n, 3), np.float32) if getattr(self, name) is None else getattr(self, name)
            for name, n in _BLOCKS[self.model_type]
        ]
        return np.concatenate(parts, axis=1).reshape(frames, -1)

    def to_motion(self, *, default_fps: float = 30.0) -> Any:
        """The file as a :class:`~smplcore.motion.Motion` (float64). A file without motion gives one frame in the
        rest pose; ``vertexOffsets`` have no place in a motion and are dropped with a warning."""
        from smplcore.motion import Motion

        model_type = {"smil": "smpl", "supr": "smplx", "smplxs": "smplx"}.get(self.model_type, self.model_type)
        if model_type != self.model_type:
            warn(f"{self.source}: reading a {self.model_type} file as a {model_type} motion (same pose layout)")
        if self.vertex_offsets is not None and np.any(self.vertex_offsets):
            warn(f"{self.source}: vertexOffsets (per-vertex details) are not part of a motion; dropped")
        frames = self.num_frames
        return Motion(
            poses=self.full_pose().astype(np.float64),
            trans=np.zeros((frames, 3)) if self.transl is None else self.transl.astype(np.float64),
            betas=np.zeros(0) if self.betas is None else self.betas.astype(np.float64),
            fps=float(self.fps) if self.fps else default_fps,
            model_type=model_type,
            gender=self.gender,
            expression=None if self.expression is None else self.expression.astype(np.float64),
            source=self.source,
        )

    @classmethod
    def from_motion(cls, motion: Any) -> SmplFile:
        """A :class:`~smplcore.motion.Motion` of SMPL, SMPL+H or SMPL-X as a ``.smpl`` file. DMPL soft tissue has no
        key in the format: dropped with a warning."""
        if motion.model_type not in ("smpl", "smplh", "smplx"):
            raise ValueError(
                f"motion: the .smpl format holds SMPL, SMPL+H and SMPL-X poses (smplVersion), not {motion.model_type!r}"
            )
        if motion.dmpls is not None:
            warn("the .smpl format has no DMPL soft tissue: dropping the motion's dmpls")
        gender = motion.gender if motion.gender in GENDERS else "neutral"
        if gender != motion.gender:
            warn(f"the .smpl format knows genders {GENDERS}; writing {motion.gender!r} as 'neutral'")
        frames = motion.num_frames
        joints = np.asarray(motion.poses, np.float32).reshape(frames, -1, 3)
        blocks: dict[str, Any] = {}
        start = 0
        for name, n in _BLOCKS[motion.model_type]:
            blocks[name] = joints[:, start : start + n]
            start += n
        expression = None
        if motion.expression is not None and motion.model_type == "smplx":
            expression = np.asarray(motion.expression, np.float32)
        elif motion.expression is not None:
            warn(f"a {motion.model_type} .smpl file has no expression: dropping the motion's expression")
        return cls(
            model_type=motion.model_type,
            gender=gender,
            betas=np.asarray(motion.betas, np.float32).reshape(-1),
            frame_count=frames,
            fps=float(motion.fps),
            transl=np.asarray(motion.trans, np.float32),
            expression=expression,
            source=str(motion.source),
            **blocks,
        )


def read_smpl(path: str | Path) -> SmplFile:
    """Read a ``.smpl`` file (no pickles); unknown keys are ignored with a warning, wrong dtypes or shapes are a
    :class:`~smplcore.errors.ModelFileError` naming the key."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    try:
        archive = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise ModelFileError(path, f"not a .smpl (npz) file: {exc}") from None
    values: dict[str, Any] = {"codec_version": 1}
    with archive:
        unknown = sorted(set(archive.files) - set(_KEYS))
        if unknown:
            warn(f"{path}: ignoring unknown key(s) {unknown}")
        for key in archive.files:
            if key not in _KEYS:
                continue
            try:
                value = archive[key]
            except ValueError as exc:  # an object array
                raise ModelFileError(path, f"unreadable without pickle: {exc}", key=key) from None
            kind = "i" if key in _INT_KEYS else "f"
            if value.dtype.kind not in (("i", "u") if kind == "i" else ("f", "i", "u")):
                raise ModelFileError(
                    path, f"expected {'an integer' if kind == 'i' else 'a float'}, found {value.dtype}", key=key
                )
            if key in _INT_KEYS or key == "frameRate":
                if value.size != 1:
                    raise ModelFileError(path, f"expected a scalar, found shape {value.shape}", key=key)
                value = value.reshape(())
            elif not np.all(np.isfinite(value)):
                raise ModelFileError(path, "contains NaN or infinite values", key=key)
            values[_KEYS[key]] = value
    try:
        if "model_type" in values:
            values["model_type"] = SMPL_VERSIONS[int(values["model_type"])]
        if "gender" in values:
            values["gender"] = GENDERS[int(values["gender"])]
    except IndexError:
        bad = "smplVersion" if "model_type" in values and isinstance(values["model_type"], np.ndarray) else "gender"
        raise ModelFileError(path, "unknown code", key=bad) from None
    for name in ("codec_version", "frame_count"):
        if isinstance(values.get(name), np.ndarray):
            values[name] = int(values[name])
    if "fps" in values:
        values["fps"] = float(values["fps"])
    for name, value in values.items():
        if isinstance(value, np.ndarray):
            values[name] = value.astype(np.float32)
    return SmplFile(source=str(path), **values)


def write_smpl(path: str | Path, data: SmplFile) -> Path:
    """Write ``data`` as a ``.smpl`` file: int32 / float32 arrays under the format's camelCase keys, compressed."""
    path = Path(path)
    arrays: dict[str, np.ndarray] = {}
    for key, name in _KEYS.items():
        value = getattr(data, name)
        if value is None:
            continue
        if name == "model_type":
            value = SMPL_VERSIONS.index(value)
        elif name == "gender":
            value = GENDERS.index(value)
        arrays[key] = np.asarray(value, np.int32 if key in _INT_KEYS else np.float32)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as fh:
        np.savez_compressed(fh, **arrays)  # type: ignore[arg-type]
    return path


def save_smpl(path: str | Path, source: Any, model: Any = None, *, fps: float | None = None) -> Path:
    """Write a motion or parameter set as ``.smpl``.

    Parameters
    ----------
    path : the ``.smpl`` file to write.
    source : a :class:`~smplcore.motion.Motion`, a motion / parameter / ``.smpl`` file, a dict of model
        keyword arrays (``betas``, ``global_orient``, ``body_pose``, ``transl``, ...) or a
        :class:`~smplcore.fit.FitResult` (one frame per fitted body).
    model : the body model a parameter set belongs to (a :class:`smplcore.BodyModel`; needed for parameter
        sets, whose PCA hands and mean hand pose it resolves into the absolute axis-angle poses the format
        holds). Motions need none.
    fps : frame rate (default: the motion's, 30 for a parameter set).
    """
    from smplcore.export.inputs import fit_result_params, load_input
    from smplcore.motion import Motion

    if isinstance(source, (str, Path)):
        source = load_input(source, fps=fps)
    source = fit_result_params(source)
    if isinstance(source, dict) and "poses" in source:
        from smplcore.export.inputs import _motion_input

        source = _motion_input(source, fps=fps)
    if not isinstance(source, Motion):
        if model is None:
            raise ValueError("model: a parameter set needs its body model to be written as .smpl (model=...)")
        source = _params_motion(model, source, fps)
    elif fps is not None:
        source = replace(source, fps=float(fps))
    return write_smpl(path, SmplFile.from_motion(source))


def _params_motion(model: Any, params: Any, fps: float | None) -> Any:
    """A parameter set through the model (PCA hands, mean hand pose resolved) as a Motion of absolute rotations."""
    from scipy.spatial.transform import Rotation

    from smplcore.export.animation import prepare_animation
    from smplcore.motion import Motion

    if model.model_type not in ("smpl", "smplh", "smplx"):
        raise ValueError(
            f"model: the .smpl format holds SMPL, SMPL+H and SMPL-X bodies (smplVersion), not {model.model_type!r}"
        )
    anim = prepare_animation(model, params, fps=fps)
    frames, joints = anim.rotations.shape[:2]
    poses = Rotation.from_matrix(anim.rotations.reshape(-1, 3, 3)).as_rotvec().reshape(frames, joints * 3)
    gender = str(params.get("gender", "neutral")) if hasattr(params, "get") else "neutral"
    return Motion(
        poses=poses,
        trans=anim.transl,
        betas=anim.betas,
        fps=anim.fps,
        model_type=model.model_type,
        gender=gender if gender in GENDERS else "neutral",
        expression=anim.expression if model.model_type == "smplx" else None,
        source="<parameters>",
    )


def amass_to_smpl(source: str | Path, target: str | Path, *, fps: float | None = None) -> Path:
    """Convert an AMASS ``.npz`` (SMPL, SMPL+H or SMPL-X) to ``.smpl``; ``fps`` for a motion that states none."""
    from smplcore.motion import load_motion

    return write_smpl(target, SmplFile.from_motion(load_motion(source, default_fps=fps)))


def smpl_to_amass(source: str | Path, target: str | Path) -> Path:
    """Convert a ``.smpl`` file to an AMASS-style ``.npz`` (``poses``, ``trans``, ``betas``, ``gender``, the frame
    rate, ``surface_model_type``, ``expression`` for SMPL-X)."""
    from smplcore.motion import save_motion

    return save_motion(read_smpl(source).to_motion(), target)


# ----------------------------------------------------------------------------------- Blender add-on npz

_BLENDER_TYPES = ("smplx", "smplh")
#: rotation taking the model's Y-up frame to Blender's / AMASS's Z-up frame: +90 deg about X
Y_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def _reorient(motion: Any, rotation: np.ndarray, pelvis: np.ndarray) -> Any:
    """The motion turned by ``rotation`` about the origin: the root orientation is pre-multiplied, and the
    translation moves so that the pelvis (rest position ``pelvis``) lands where the turned body puts it."""
    from scipy.spatial.transform import Rotation

    poses = np.array(motion.poses, dtype=np.float64)
    root = Rotation.from_matrix(rotation) * Rotation.from_rotvec(poses[:, :3])
    poses[:, :3] = root.as_rotvec()
    trans = (np.asarray(motion.trans) + pelvis) @ rotation.T - pelvis
    return replace(motion, poses=poses, trans=trans)


def _pelvis(model: Any, motion: Any) -> np.ndarray:
    if model is None:
        raise ValueError(
            "model: turning a motion between Y-up and Z-up moves its translation by the pelvis rest position, "
            "which needs the body model (model=...)"
        )
    betas = np.asarray(motion.betas, np.float64).reshape(-1)[: model.num_betas]
    return np.asarray(model.rest_pose(betas)[1][0], np.float64)


def save_blender_npz(path: str | Path, motion: Any, *, up: str = "y", model: Any = None) -> Path:
    """Write ``motion`` in the layout the SMPL-X Blender add-ons import (see the module docs).

    Parameters
    ----------
    path : the ``.npz`` to write.
    motion : a SMPL-X, SMPL+H or SMPL :class:`~smplcore.motion.Motion` (SMPL is written as SMPL+H: the
        joints carried over by name; SMPL's two hand joints, which SMPL+H lacks, are dropped with a warning
        when they move).
    up : ``"y"`` (the model's frame; import with anim_format ``SMPL-X``) or ``"z"`` (turned +90 deg about X
        like AMASS; import with anim_format ``AMASS``).
    model : the body model (needed for ``up="z"``: the translation moves with the pelvis rest position).
    """
    if up not in ("y", "z"):
        raise ValueError(f"up: expected 'y' or 'z', got {up!r}")
    if motion.model_type == "smpl":
        from smplcore.family.specs import get_spec

        joints = np.asarray(motion.poses).reshape(motion.num_frames, -1, 3)
        names = list(get_spec("smpl").joint_names)
        hands = [names.index(n) for n in ("left_hand", "right_hand")]
        if np.any(joints[:, hands]):
            warn(
                "save_blender_npz: SMPL's left_hand/right_hand joints have no SMPL+H twin; their rotations are dropped"
            )
        params = motion.model_params("smplh")
        poses = np.concatenate([params[b] for b in get_spec("smplh").block_offsets()], axis=1)
        motion = replace(motion, poses=poses, model_type="smplh", expression=None)
    if motion.model_type not in _BLENDER_TYPES:
        raise ValueError(f"motion: the Blender add-ons import SMPL-X or SMPL+H poses, not {motion.model_type!r}")
    if up == "z":
        motion = _reorient(motion, Y_TO_Z_UP, _pelvis(model, motion))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(
        path,
        poses=np.asarray(motion.poses, np.float64),
        trans=np.asarray(motion.trans, np.float64),
        betas=np.asarray(motion.betas, np.float64),
        gender=np.array(motion.gender),
        mocap_frame_rate=np.array(float(motion.fps)),
        surface_model_type=np.array(motion.model_type),
    )
    return path


def load_blender_npz(path: str | Path, *, up: str = "y", model: Any = None) -> Any:
    """Read a Blender add-on ``.npz`` back as a Y-up :class:`~smplcore.motion.Motion` (``up="z"``: the file is
    Z-up, anim_format ``AMASS``; turned back, which needs the model)."""
    from smplcore.motion import load_motion

    if up not in ("y", "z"):
        raise ValueError(f"up: expected 'y' or 'z', got {up!r}")
    motion = load_motion(path)
    if motion.poses.shape[1] not in (156, 165):
        raise ShapeError(f"{path}: poses: expected (T, 165) or (T, 156), got {motion.poses.shape}")
    if up == "z":
        motion = _reorient(motion, Y_TO_Z_UP.T, _pelvis(model, motion))
    return motion
