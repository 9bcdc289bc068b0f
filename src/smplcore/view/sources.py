"""What the viewer and the video writer show: model files, motions (AMASS ``.npz``, our ``.bvh`` exports),
parameter sets (fit outputs) and target keypoints, read into plain arrays.

A :class:`Source` is one command-line argument; :func:`load_source` tells the kinds apart. A BVH motion is
kept as its joint rotations (:class:`BvhMotion`) and turned into a :class:`~smplcore.motion.Motion` for a
given model by :meth:`BvhMotion.to_motion`, since its root channel holds absolute positions.
"""

from __future__ import annotations

import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ModelFileError, ShapeError

# Keys that only a body-model file has (a motion or parameter set never does).
_MODEL_KEYS = {"v_template", "shapedirs", "weights", "J_regressor"}
_MODEL_SUFFIXES = {".pkl"}
_KEYPOINT_KEYS = ("keypoints", "keypoints3d", "joints", "points", "target")
# Units a BVH file may be written in, as multiples of metres; a file's scale snaps to one within 15%.
_UNITS = (1.0, 100.0, 1000.0, 1.0 / 0.0254)


@dataclass(frozen=True)
class BvhMotion:
    """Skeleton motion read from a BVH file.

    Attributes
    ----------
    names : the J joint names, in the file's order (depth first).
    rotations : (T, J, 3, 3) local rotation of each joint per frame.
    root_positions : (T, 3) the root channel's positions, in the file's unit.
    offsets : (J, 3) offset of each joint from its parent, in the file's unit.
    fps : frames per second.
    source : the file.
    """

    names: tuple[str, ...]
    rotations: np.ndarray
    root_positions: np.ndarray
    offsets: np.ndarray
    fps: float
    source: str

    @property
    def num_frames(self) -> int:
        return int(self.rotations.shape[0])

    def to_motion(self, model: Any) -> Any:
        """The motion on ``model`` (a :class:`smplcore.BodyModel`): joints matched by name, the file's unit
        found from its bone lengths against the model's (metres, cm, mm or inches), translation relative to
        the model's rest root joint (zero betas: a BVH has no shape coefficients).

        Raises
        ------
        ValueError
            when no joint name of the file is one of the model's.
        """
        from scipy.spatial.transform import Rotation

        from smplcore.motion import Motion

        names = list(model.skeleton_joint_names)
        index = {name: j for j, name in enumerate(self.names)}
        matched = [(j, index[n]) for j, n in enumerate(names) if n in index]
        if not matched:
            raise ValueError(
                f"{self.source}: none of its {len(self.names)} joints ({', '.join(self.names[:4])}, ...) is a "
                f"joint of the {model.model_type} model; a BVH written by `smplcore export` for that model works"
            )
        _, rest = model.rest_pose()
        parents = model.parents
        model_len = sum(float(np.linalg.norm(rest[j] - rest[parents[j]])) for j, _ in matched if parents[j] >= 0)
        file_len = sum(float(np.linalg.norm(self.offsets[k])) for j, k in matched if parents[j] >= 0)
        scale = file_len / model_len if model_len > 0 and file_len > 0 else 1.0
        unit = min(_UNITS, key=lambda u: abs(np.log(scale / u)))
        if abs(np.log(scale / unit)) < np.log(1.15):
            scale = unit
        frames = self.num_frames
        rotvecs = np.zeros((frames, len(names), 3))
        for j, k in matched:
            rotvecs[:, j] = Rotation.from_matrix(self.rotations[:, k]).as_rotvec()
        poses, model_type = _as_pose_layout(rotvecs, model)
        trans = self.root_positions / scale - rest[0]
        return Motion(
            poses=poses, trans=trans, betas=np.zeros(10), fps=self.fps, model_type=model_type, source=self.source
        )


def _as_pose_layout(rotvecs: np.ndarray, model: Any) -> tuple[np.ndarray, str]:
    """(T, J, 3) rotations in ``model``'s joint order as (T, 3 J) poses of a Motion layout that holds them."""
    from smplcore.family.specs import get_spec
    from smplcore.motion import POSE_WIDTH

    names = list(model.skeleton_joint_names)
    layout = model.model_type if model.model_type in POSE_WIDTH else "smpl"
    target = list(get_spec(layout).joint_names)
    out = np.zeros((rotvecs.shape[0], len(target), 3))
    for j, name in enumerate(names):
        if name in target:
            out[:, target.index(name)] = rotvecs[:, j]
    return out.reshape(rotvecs.shape[0], -1), layout


def read_bvh(path: str | Path) -> BvhMotion:
    """Read a BVH file (``.bvh`` or ``.bvh.gz``) with :func:`smplcore.skeletons.read_bvh`.

    Raises
    ------
    ModelFileError
        naming the file (and the line) when it cannot be parsed.
    """
    from smplcore.io import open_input
    from smplcore.skeletons import read_bvh as read_clip

    path = Path(path)
    open_input(path, "a BVH motion (.bvh)")[0].close()  # a FIFO or device is refused before it is opened
    clip = read_clip(path)
    return BvhMotion(
        names=clip.joint_names,
        rotations=clip.rotations,
        root_positions=clip.root_positions,
        offsets=clip.offsets,
        fps=clip.fps,
        source=str(path),
    )


@dataclass
class Source:
    """One thing to show. Exactly one of ``model_path``, ``motion``, ``bvh`` and ``params`` is set, or none
    (the model alone at rest).

    Attributes
    ----------
    label : shown in the viewer (the file name).
    model_path : a body-model file to open.
    motion : a :class:`~smplcore.motion.Motion` (AMASS-style ``.npz``, ``.json`` with ``poses``).
    bvh : a :class:`BvhMotion`.
    params : a parameter set: model keyword arrays (``betas``, ``body_pose``, ...), (n,) or (T, n).
    """

    label: str = "body"
    model_path: Path | None = None
    motion: Any = None
    bvh: BvhMotion | None = None
    params: dict[str, Any] | None = None

    @property
    def fps(self) -> float | None:
        if self.motion is not None:
            return float(self.motion.fps)
        if self.bvh is not None:
            return self.bvh.fps
        if self.params is not None and "fps" in self.params:
            return float(np.asarray(self.params["fps"]).reshape(-1)[0])
        return None


def _is_model_file(path: Path) -> bool:
    if path.suffix.lower() in _MODEL_SUFFIXES:
        return True
    if path.suffix.lower() != ".npz" or not zipfile.is_zipfile(path):
        return False
    try:
        with zipfile.ZipFile(path) as archive:
            keys = {name[:-4] if name.endswith(".npy") else name for name in archive.namelist()}
    except (zipfile.BadZipFile, NotImplementedError, OSError, ValueError, EOFError) as exc:
        raise ModelFileError(path, f"not a readable .npz archive ({type(exc).__name__}: {exc})") from None
    return bool(keys & _MODEL_KEYS) and "poses" not in keys


def load_source(path: str | Path) -> Source:
    """Read one viewer / render argument: a model file (``.pkl``, or a ``.npz`` with ``v_template``), a
    motion (AMASS ``.npz``, ``.json`` with ``poses``, ``.bvh``) or a parameter set (``.npz`` / ``.json``).

    Raises
    ------
    FileNotFoundError, ValueError, ModelFileError
        naming the file.
    """
    from smplcore.export.animation import load_input
    from smplcore.io import open_input
    from smplcore.motion import Motion

    path = Path(path)
    if not path.exists() and not path.is_symlink():
        raise FileNotFoundError(f"{path}: no such file")
    if not path.is_dir():  # a FIFO, device, socket or link loop is refused here, before anything opens it
        open_input(path, "a motion, parameter set or model file")[0].close()
    if path.is_dir() or _is_model_file(path):
        return Source(label=path.name, model_path=path)
    if path.suffix.lower() == ".bvh":
        return Source(label=path.name, bvh=read_bvh(path))
    loaded = load_input(path)
    if isinstance(loaded, Motion):
        return Source(label=path.name, motion=loaded)
    return Source(label=path.name, params=dict(loaded))


def load_keypoints(path: str | Path) -> np.ndarray:
    """Target 3D keypoints from ``.npy`` or ``.npz`` (key ``keypoints``, ``joints``, ``points`` or ``target``,
    or its only array): (K, 3) for one frame or (T, K, 3); a last axis of 4 (x, y, z, confidence) is cut to 3.

    Raises
    ------
    ShapeError, ModelFileError
        naming the file and the shape found.
    """
    from smplcore.io import numeric_array, read_arrays

    path = Path(path)
    if not path.exists() and not path.is_symlink():
        raise FileNotFoundError(f"{path}: no such file")
    data = read_arrays(path, "a keypoint file (.npy or .npz)")
    key = None
    if isinstance(data, Mapping):
        files = list(data)
        key = next((k for k in _KEYPOINT_KEYS if k in files), None)
        if key is None and len(files) == 1:
            key = files[0]
        if key is None:
            raise ModelFileError(path, f"no keypoints; expected one of {_KEYPOINT_KEYS}, found {files}")
        data = data[key]
    arr = numeric_array(path, data, key).astype(np.float64)
    if arr.ndim not in (2, 3) or arr.shape[-1] not in (3, 4):
        raise ShapeError(f"{path}: expected keypoints of shape (K, 3) or (T, K, 3), got {arr.shape}")
    arr = arr[..., :3]
    return arr[None] if arr.ndim == 2 else arr
