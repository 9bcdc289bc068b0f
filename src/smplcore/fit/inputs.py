"""What ``smplcore fit`` reads and writes: one input (2D keypoints, 3D joints, another model's motion) to
one AMASS-style motion ``.npz`` of the fitted model.

Inputs: a folder of OpenPose JSON files (one sequence; its people tracked, ``person`` picks one or
``"all"``), a COCO keypoint JSON (every annotated person an independent body with its own shape, in image
order; :mod:`smplcore.fit.inputs2d`), a ``.npy`` of 3D joints (T, n, 3) (units
checked: :mod:`smplcore.fit.skeleton_inputs`), a BVH motion capture (``.bvh``, ``.bvh.gz``: skeleton and units
detected, one person), or an AMASS-style ``.npz`` of another model (converted). The output is what
:func:`smplcore.motion.load_motion` (``smplcore export`` / ``smplcore process``) reads, plus
``fit_error`` (T,) (pixels for 2D, metres otherwise), ``fit_converged`` (T,) and ``fit_kind``; for 2D
inputs also ``fit_focal`` (T, 2), the focal length each frame was fitted with (given or estimated), and the
camera of each frame: ``camera_intrinsics`` (T, 3, 3) and ``camera_extrinsics`` (T, 4, 4), world to camera
in OpenCV axes (x right, y down, z forward), ``X_cam = E @ [X_world, 1]``.

The world of a 2D fit (``fit_frame``): without given extrinsics, Y up, the camera level (looking along
world -Z, so that a body facing the camera faces +Z as SMPL's rest pose does), the lowest vertex of the
sequence (of each image's people, for COCO) on the ground ``y = 0`` and the first frame's pelvis above the
origin; with ``extrinsics``, the world they are given in (nothing moved).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ModelFileError


@dataclass(frozen=True)
class FitSettings:
    """The options of a ``smplcore fit`` run (plain values, so that workers can receive them)."""

    model_type: str = "open"
    model_path: str | None = None
    gender: str = "neutral"
    convention: str | None = None
    joint_names: tuple[str, ...] | None = None
    joint_weights: tuple[float, ...] | None = None
    focal: tuple[float, ...] | None = None
    center: tuple[float, float] | None = None
    image_size: tuple[float, float] | None = None
    fps: float = 30.0
    person: int | str = 0  # OpenPose: a track (0: the person seen longest) or "all"
    smoothness: float = 1e-3
    source_model_path: str | None = None
    estimate_focal: bool = False  # 2D without ``focal``: estimate it from the image diagonal (else keep that)
    vposer: str | None = None
    gmm: str | None = None
    extrinsics: tuple[float, ...] | None = None  # 2D: world-to-camera (4 x 4 row-major, OpenCV axes); None: level
    max_iter: int | None = None  # the solvers' iteration budget (None: each fit's default)
    extra: dict[str, Any] = field(default_factory=dict)
    overlay: str | None = None  # 2D: a .png of the first image's / frame's fit drawn over ``image``
    image: str | None = None  # 2D: the photo the overlay is drawn on (None: a blank canvas of the image size)
    skeleton: str | None = None  # BVH / .npy: the skeleton map (None: detected from a BVH's joint names)
    units: str | None = None  # BVH / .npy: cm, m, mm, in, cmu, ft or metres per unit (None: detected)


def input_kind(path: Path) -> str:
    """``openpose`` (a folder of JSON files), ``coco`` (a JSON file), ``joints`` (``.npy``), ``bvh`` (``.bvh``,
    ``.bvh.gz``) or ``motion`` (``.npz``)."""
    from smplcore.fit.skeleton_inputs import is_bvh

    if is_bvh(path) and not path.is_dir():
        return "bvh"
    if path.is_dir():
        if any(p.suffix.lower() == ".json" for p in path.iterdir()):
            return "openpose"
        raise ValueError(f"{path}: a folder holding no OpenPose .json files")
    kinds = {".json": "coco", ".npy": "joints", ".npz": "motion"}
    kind = kinds.get(path.suffix.lower())
    if kind is None:
        raise ValueError(
            f"{path}: unsupported input {path.suffix!r}; expected an OpenPose folder, .json, .npy, .npz or .bvh(.gz)"
        )
    return kind


def build_model(
    settings: FitSettings, model_type: str | None = None, model_path: str | None = None, gender: str | None = None
) -> Any:
    """The NumPy model the fits use (full-pose hands, flat hand mean: AMASS's layout), in ``gender``
    (default ``settings.gender``; the open model has three genders too)."""
    from smplcore import BodyModel

    model_type = model_type or settings.model_type
    path = model_path if model_path is not None else settings.model_path
    gender = gender or settings.gender
    if path is None:
        if model_type not in ("open", None):
            raise ValueError(f"--model-path: a {model_type} model needs its file or folder (only 'open' ships)")
        return BodyModel(model_type="open", gender=gender, dtype=np.float64)
    options: dict[str, Any] = {"dtype": np.float64}
    if model_type in ("smplh", "smplx", "mano"):
        options.update(use_pca=False, flat_hand_mean=True)
    return BodyModel(path, model_type=model_type, gender=gender, **options)


_PRIORS: dict[tuple[str, str], Any] = {}


def _priors(settings: FitSettings) -> dict[str, Any]:
    """The VPoser / GMM priors of ``settings``, each read once per process."""
    from smplcore.fit import GMMPrior, VPoserPrior

    out = {}
    for name, kind in (("vposer", VPoserPrior), ("gmm", GMMPrior)):
        path = getattr(settings, name)
        if path is not None:
            if (name, path) not in _PRIORS:
                _PRIORS[(name, path)] = kind.load(path)
            out[name] = _PRIORS[(name, path)]
    return out


#: World-to-camera rotation of the default camera: level, looking along world -Z, OpenCV axes (y down).
LEVEL = np.diag([1.0, -1.0, -1.0])


def _extrinsics(settings: FitSettings) -> tuple[np.ndarray, np.ndarray]:
    """World-to-camera rotation (3, 3) and translation (3,) of a 2D input's camera."""
    if settings.extrinsics is None:
        return LEVEL, np.zeros(3)
    matrix = np.asarray(settings.extrinsics, np.float64).reshape(4, 4)
    return matrix[:3, :3], matrix[:3, 3]


def _camera(settings: FitSettings, size: tuple[float, float] | None = None):
    """The camera of a 2D input and whether its focal length is to be estimated."""
    from smplcore.fit.camera import Camera

    rotation, translation = _extrinsics(settings)
    size = settings.image_size or size
    if settings.focal is not None:
        center = settings.center
        if center is None and size is not None:
            center = (size[0] / 2.0, size[1] / 2.0)
        if center is None:
            raise ValueError("--center: the principal point is needed with --focal (or give --image-size)")
        focal = settings.focal[0] if len(settings.focal) == 1 else settings.focal
        return Camera(focal, center, rotation, translation, image_size=size), False
    if size is not None:
        guess = Camera.from_image_size(*size)
        return guess.replace(rotation=rotation, translation=translation), settings.estimate_focal
    raise ValueError("camera: 2D keypoints need the camera: pass --focal and --center, or --image-size W,H")


def _matrices(camera: Any) -> tuple[np.ndarray, np.ndarray]:
    """Intrinsics (3, 3) and extrinsics (4, 4, world to camera) of a :class:`smplcore.fit.Camera`."""
    k = np.eye(3)
    k[[0, 1], [0, 1]] = camera.focal
    k[:2, 2] = camera.center
    e = np.eye(4)
    e[:3, :3], e[:3, 3] = camera.rotation, camera.translation
    return k, e


def _ground(model: Any, params: dict[str, np.ndarray], extrinsics: np.ndarray, rows: np.ndarray) -> None:
    """Move the bodies ``rows`` (and their cameras) so that their lowest vertex is at y = 0 and the first
    one's pelvis above the origin: a translation of the world, in place."""
    lowest = np.inf
    root = None
    for start in range(0, len(rows), 256):  # a long sequence in chunks of meshes
        chunk = rows[start : start + 256]
        out = model(**{k: v[chunk] for k, v in params.items() if k != "betas" or v.ndim == 2})
        lowest = min(lowest, float(np.asarray(out.vertices)[..., 1].min()))
        if root is None:
            root = np.asarray(out.joints, np.float64)[0, 0]
    assert root is not None  # rows is not empty
    shift = np.array([-root[0], -lowest, -root[2]])
    params["transl"][rows] += shift
    extrinsics[rows, :3, 3] -= extrinsics[rows, :3, :3] @ shift


def _coco_image_sizes(path: Path) -> dict[Any, tuple[float, float]]:
    from smplcore.io import read_json

    doc = read_json(path, "a COCO keypoint file (.json)")
    sizes = {}
    images = doc.get("images", []) if isinstance(doc, dict) else []
    for image in images if isinstance(images, list) else []:
        if isinstance(image, dict) and image.get("width") and image.get("height"):
            try:
                size = (float(image["width"]), float(image["height"]))
                sizes[image.get("id")] = size
            except (TypeError, ValueError, OverflowError):
                raise ModelFileError(path, f"image {image.get('id')!r}: width and height must be numbers") from None
    return sizes


def fit_input(path: str | Path, settings: FitSettings, model: Any = None) -> tuple[dict[str, np.ndarray], dict]:
    """Fit one input; returns the output arrays and a summary (kind, frames, not-converged frames, errors)."""
    from smplcore import fit

    path = Path(path)
    kind = input_kind(path)
    model = build_model(settings) if model is None else model
    extra = dict(settings.extra)
    if settings.max_iter is not None:
        extra["max_iter"] = settings.max_iter
    labels = None
    unseen: list[str] = []
    notes: list[str] = []
    fps = settings.fps
    if kind in ("openpose", "coco"):
        from smplcore.fit.inputs2d import fit_2d

        found = fit_2d(path, kind, settings, model, extra)
        params, error, converged, labels = found.params, found.error, found.converged, found.labels
        focal, intrinsics, extrinsics, unseen = found.focal, found.intrinsics, found.extrinsics, found.unseen
        betas = params["betas"] if found.people else params["betas"][0]  # different people: a shape per row
    elif kind == "joints":
        from smplcore.io import numeric_array, read_arrays

        joints = numeric_array(path, read_arrays(path, "a joints file (.npy)"), kinds="iuf")
        if joints.ndim != 3 or joints.shape[-1] != 3:
            raise ModelFileError(path, f"expected joints of shape (T, J, 3), found {joints.shape}")
        names: Sequence[str] | None = settings.joint_names
        weights = None
        if names is None and settings.convention is not None and settings.skeleton is None:
            names, weights = _convention_joints(model, settings.convention, joints.shape[1])
        if settings.joint_weights is not None:
            if len(settings.joint_weights) != joints.shape[1]:
                raise ValueError(
                    f"--joint-weights: {len(settings.joint_weights)} weights for the {joints.shape[1]} joints of {path}"
                )
            given = np.asarray(settings.joint_weights, np.float64)
            weights = given if weights is None else np.asarray(weights, np.float64) * given
        from smplcore.fit.skeleton_inputs import joints_in_metres

        joints, names, weights, notes = joints_in_metres(joints, names, weights, settings, model)
        r = fit.fit_joints(model, joints, names, weights, share_betas=True, smoothness=settings.smoothness, **extra)
        assert r.joint_error is not None  # fit_joints always measures it
        params, error, converged = {k: np.asarray(v) for k, v in r.params.items()}, r.joint_error, r.converged
        betas = params["betas"][0]
    elif kind == "bvh":
        from smplcore.fit.skeleton_inputs import bvh_targets

        targets = bvh_targets(path, settings, model)
        notes, fps = list(targets.notes), float(targets.fps or settings.fps)
        r = fit.fit_joints(model, *targets, share_betas=True, smoothness=settings.smoothness, **extra)
        assert r.joint_error is not None
        params, error, converged = {k: np.asarray(v) for k, v in r.params.items()}, r.joint_error, r.converged
        betas = params["betas"][0]
    else:
        from smplcore.motion import load_motion

        motion = load_motion(path)
        source_type = "open" if settings.source_model_path is None else motion.model_type
        # the source mesh in the gender its file names (--gender is the target's)
        source = build_model(settings, source_type, settings.source_model_path, gender=motion.gender)
        src = motion.model_params(source_type, list(source.skeleton_joint_names))
        src["betas"] = src["betas"][:, : source.num_betas]
        r = fit.convert(src, source, model, share_betas=True, **extra)
        assert r.vertex_error is not None  # convert always measures it
        params, error, converged = {k: np.asarray(v) for k, v in r.params.items()}, r.vertex_error, r.converged
        betas = params["betas"][0]
    arrays = _motion_arrays(model, params, betas, settings, fps)
    arrays.update(fit_error=error, fit_converged=converged, fit_kind=np.array(kind))
    if labels is not None:
        arrays.update(labels)
    if kind in ("openpose", "coco"):
        arrays.update(fit_focal=focal, camera_intrinsics=intrinsics, camera_extrinsics=extrinsics)
        arrays["fit_frame"] = np.array("world" if settings.extrinsics is None else "given extrinsics")
    summary = {
        "kind": kind,
        "frames": len(error),
        "not_converged": np.flatnonzero(~converged & np.isfinite(error)).tolist(),
        "missing": np.flatnonzero(~np.isfinite(error)).tolist(),  # no detection: the nearest frame's fit
        "mean_error": float(np.nanmean(error)),
        "error_unit": "px" if kind in ("openpose", "coco") else "m",
        "unit": "bodies" if labels is not None else "frames",  # COCO, all tracks: one row per person and image
        "images_without_person": unseen,
        "notes": notes,  # what was detected or converted (a BVH's skeleton and units, joints in centimetres)
    }
    if kind in ("openpose", "coco"):
        summary["people"] = found.tracks if kind == "openpose" else len(error)
        if settings.overlay is not None:
            from smplcore.fit.inputs2d import write_overlay

            summary["overlay"] = str(write_overlay(model, found, settings))
    return arrays, summary


def _gather(parts: list[tuple[np.ndarray, np.ndarray]], count: int) -> np.ndarray:
    out = np.zeros((count, *parts[0][1].shape[1:]))
    for rows, value in parts:
        out[rows] = value
    return out


def _convention_joints(model: Any, convention: str, count: int) -> tuple[list[str], np.ndarray]:
    """Model joint names for the points of ``convention`` (points the model lacks get weight 0)."""
    from smplcore import keypoints as kp

    plan = kp.plan(kp.layout(convention), model)
    inverse = kp.plan(model, convention)
    if len(inverse.dst) != count:
        raise ValueError(f"--convention: {convention} has {len(inverse.dst)} points, the joints file has {count}")
    names = list(model.joint_names)
    picked, weights = [], np.zeros(count)
    for k in range(count):
        i = inverse.first[k]
        ok = inverse.mask[k] and inverse.first[k] == inverse.second[k] and inverse.how[k] == "exact"
        picked.append(names[i] if ok else names[0])
        weights[k] = 1.0 if ok else 0.0
    del plan
    return picked, weights


def _motion_arrays(
    model: Any, params: dict[str, np.ndarray], betas: np.ndarray, settings: FitSettings, fps: float
) -> dict:
    """AMASS-style arrays of fitted parameters (``poses`` in the model's block order)."""
    from smplcore.motion import POSE_WIDTH

    blocks = [np.asarray(params[b]).reshape(len(params["transl"]), -1) for b in model.pose_blocks]
    poses = np.concatenate(blocks, axis=1)
    model_type = model.model_type  # the model fitted ("open" too: its betas are its own, not SMPL's)
    if POSE_WIDTH.get(model_type) != poses.shape[1]:
        raise ModelFileError(
            "<fit>", f"the {model.model_type} fit gives {poses.shape[1]} pose values, not an AMASS layout"
        )
    arrays = {
        "poses": poses,
        "trans": np.asarray(params["transl"], np.float64),
        "betas": np.asarray(betas, np.float64),
        "gender": np.array(settings.gender),
        "surface_model_type": np.array(model_type),
        ("mocap_frame_rate" if model_type == "smplx" else "mocap_framerate"): np.array(float(fps)),
    }
    if "expression" in params:
        arrays["expression"] = np.asarray(params["expression"], np.float64)
    return arrays
