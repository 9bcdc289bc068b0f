"""A real skeleton's motion as fitting targets: model joint positions in metres, Y up, with weights.

:func:`to_model_targets` takes a BVH clip (or its path) or an array of 3D points, finds its skeleton map (by
the BVH's joint names, or the number of points), tells its units and up axis from its size (or takes them
given), and returns what :func:`smplcore.fit.fit_joints` takes::

    targets = to_model_targets("clip.bvh.gz", model=model)
    print(targets.message)                    # the skeleton, units and axes detected
    result = fit.fit_joints(model, *targets, share_betas=True)
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from smplcore.errors import ShapeError
from smplcore.skeletons.clip import BVHClip
from smplcore.skeletons.mapping import SkeletonMap
from smplcore.skeletons.units import Units, decide_units, snap_up


@dataclass(frozen=True)
class ModelTargets:
    """Fitting targets made from a real skeleton; unpacks as ``joints, joint_names, joint_weights``.

    Attributes
    ----------
    joints : (T, n, 3) target positions, metres, Y up.
    joint_names : (n,) the model joints they are.
    joint_weights : (n,) their weights.
    skeleton : the :class:`SkeletonMap` used (restricted to the model's joints).
    units : how the coordinates were scaled and turned (:class:`~smplcore.skeletons.units.Units`).
    fps : frames per second (a BVH's), or None.
    notes : what was detected or done, one sentence each (the skeleton, the units, a dropped reference frame).
    """

    joints: np.ndarray
    joint_names: tuple[str, ...]
    joint_weights: np.ndarray
    skeleton: SkeletonMap
    units: Units
    fps: float | None = None
    notes: tuple[str, ...] = ()

    def __iter__(self):
        return iter((self.joints, list(self.joint_names), self.joint_weights))

    @property
    def message(self) -> str:
        return "\n".join(self.notes)


def _leg(positions: dict[str, np.ndarray]) -> tuple[float, np.ndarray | None]:
    """Median leg length (hip → knee → ankle, mean of the sides) and the median ankles → hips direction, from
    (..., 3) positions named by model joints."""
    legs, ups = [], []
    for side in ("left", "right"):
        hip, knee, ankle = (positions.get(f"{side}_{j}") for j in ("hip", "knee", "ankle"))
        if hip is None or knee is None or ankle is None:
            continue
        legs.append(np.linalg.norm(knee - hip, axis=-1) + np.linalg.norm(ankle - knee, axis=-1))
        ups.append(hip - ankle)
    if not legs:
        return float("nan"), None
    leg = np.nanmedian(np.mean(legs, axis=0))
    up = np.mean(ups, axis=0).reshape(-1, 3)
    up = up / np.maximum(np.linalg.norm(up, axis=-1, keepdims=True), 1e-12)
    return float(leg), np.nanmedian(up, axis=0)


def _blend(skeleton: SkeletonMap, lookup: dict[str, np.ndarray], what: str) -> dict[str, np.ndarray]:
    out = {}
    for t in skeleton.targets:
        missing = [p for p in t.points if p not in lookup]
        if missing:
            raise ValueError(f"skeleton {skeleton.name}: {what} has no point {missing[0]!r} (for {t.joint})")
        out[t.joint] = sum(b * lookup[p] for p, b in zip(t.points, t.blend_weights))
    return out


def clip_units(clip: BVHClip, skeleton: SkeletonMap, units: Any = None, up: str | None = None) -> Units:
    """The :class:`Units` of a clip in file units: its leg and up axis measured on the rest pose."""
    if clip.units == "m" and clip.up == "y":
        return Units(1.0, "m", "y", float("nan"), False, "units: metres, Y up (converted before)")
    rest = dict(zip(clip.point_names, clip.rest_positions(end_sites=True)))
    leg, direction = _leg(_blend(skeleton, rest, f"{clip.source}"))
    return decide_units(leg, None if direction is None else snap_up(direction), units, up, f"skeleton of {clip.source}")


def to_metres(clip: BVHClip, skeleton: SkeletonMap, units: Any = None, up: str | None = None) -> tuple[BVHClip, Units]:
    """The clip in metres with Y up, and the :class:`Units` detected (or given) for it."""
    u = clip_units(clip, skeleton, units, up)
    if clip.units == "m" and clip.up == "y":
        return clip, u
    return clip.transformed(u.scale, u.axes, "m", "y"), u


def _bvh_targets(clip: BVHClip, skeleton: SkeletonMap) -> np.ndarray:
    """(T, n, 3) targets of a clip in metres, Y up."""
    rot, pos = clip.world_transforms()
    names = clip.point_names
    index = {n: i for i, n in enumerate(names)}
    ends = pos[:, clip.end_parents] + np.einsum("teij,ej->tei", rot[:, clip.end_parents], clip.end_offsets)
    points = np.concatenate([pos, ends], axis=1)
    parent_of = list(clip.parents) + list(clip.end_parents)  # the joint whose frame a point's offset is in
    out = np.empty((clip.num_frames, len(skeleton.targets), 3))
    for k, t in enumerate(skeleton.targets):
        missing = [p for p in t.points if p not in index]
        if missing:
            raise ValueError(f"skeleton {skeleton.name}: {clip.source} has no joint {missing[0]!r} (for {t.joint})")
        out[:, k] = np.einsum("p,tpc->tc", t.blend_weights, points[:, [index[p] for p in t.points]])
        if any(t.offset):
            frame_of = parent_of[index[t.points[0]]]
            frame = rot[:, frame_of] if frame_of >= 0 else np.broadcast_to(np.eye(3), rot[:, 0].shape)
            out[:, k] += frame @ np.asarray(t.offset, np.float64)
    return out


def to_model_targets(
    source: Any,
    skeleton: SkeletonMap | str | None = None,
    model: Any = None,
    *,
    units: Any = None,
    up: str | None = None,
    drop_reference_pose: bool = True,
) -> ModelTargets:
    """Fitting targets (model joints, metres, Y up, weights) from a real skeleton's motion.

    Parameters
    ----------
    source : a :class:`BVHClip`, the path of a ``.bvh`` / ``.bvh.gz``, or (T, K, 3) / (K, 3) points of a
        keypoint skeleton (NaN for a missing point stays NaN in the targets that use it).
    skeleton : a :class:`SkeletonMap` or its name; default: detected (a BVH's joint names; K points: the
        keypoint skeleton with K points).
    model : the model to fit (its ``joint_names`` restrict the targets); None keeps every target.
    units : ``"cm"``, ``"m"``, ``"mm"``, ``"in"``, ``"cmu"``, ``"ft"`` or metres per unit; default: detected from
        the leg length (see :mod:`smplcore.skeletons.units`).
    up : the source's up axis (``"y"``, ``"z"``, ``"-y"``, ...); default: detected (ankles → hips).
    drop_reference_pose : drop a BVH's frame 0 when it is a reference (T-) pose (``clip.reference_pose``).

    Returns
    -------
    ModelTargets, which unpacks as ``joints (T, n, 3), joint_names (n,), joint_weights (n,)`` for
    :func:`smplcore.fit.fit_joints`; ``.message`` says what was detected.
    """
    from smplcore.skeletons.maps import detect_skeleton, skeleton_map

    notes: list[str] = []
    if isinstance(source, (str, os.PathLike)):
        from smplcore.skeletons.bvh import read_bvh

        source = read_bvh(source)
    if isinstance(source, BVHClip):
        found = detect_skeleton(source.point_names) if skeleton is None else skeleton_map(skeleton)
        if skeleton is None:
            notes.append(f"skeleton: {found.name}, {found.title}; detected from the joint names")
        if found.kind != "bvh":
            raise ValueError(f"skeleton: {found.name} is a keypoint skeleton; a BVH clip needs a BVH skeleton map")
        found = found if model is None else found.resolve(model)
        clip = source
        if drop_reference_pose and clip.reference_pose:
            clip = clip.without_reference_pose()
            notes.append("frame 0 is a reference pose (T-pose), not motion: dropped")
        clip, u = to_metres(clip, found, units, up)
        notes.append(u.message)
        joints, fps = _bvh_targets(clip, found), clip.fps
    else:
        joints, found, u = _points_targets(source, skeleton, model, units, up, notes)
        fps = None
    return ModelTargets(joints, found.joint_names, found.weights, found, u, fps, tuple(notes))


def _points_targets(source, skeleton, model, units, up, notes):
    from smplcore.skeletons.maps import skeleton_for_points, skeleton_map

    points = np.asarray(source, dtype=np.float64)
    if points.ndim == 2:
        points = points[None]
    if points.ndim != 3 or points.shape[-1] != 3:
        raise ShapeError(f"source: expected points of shape (T, K, 3) or (K, 3), got {np.shape(source)}")
    if skeleton is None:
        found = skeleton_for_points(points.shape[1])
        notes.append(f"skeleton: {found.name}, {found.title}; the one with {points.shape[1]} points")
    else:
        found = skeleton_map(skeleton)
    if found.kind == "bvh" or len(found.points) != points.shape[1]:
        raise ShapeError(f"source: skeleton {found.name} has {len(found.points)} points, got {points.shape[1]}")
    found = found if model is None else found.resolve(model)
    lookup = {name: points[:, i] for i, name in enumerate(found.points)}
    named = _blend(found, lookup, "the points")
    leg, direction = _leg(named)
    u = decide_units(leg, None if direction is None else snap_up(direction), units, up, "points", points=True)
    notes.append(u.message)
    joints = np.stack([named[j] for j in found.joint_names], axis=1)
    return u.scale * joints @ u.axes.T, found, u


def leg_length(joints: np.ndarray, joint_names: Any) -> float:
    """The median leg length (hip → knee → ankle, mean of the sides) of (T, n, 3) points named by model joints;
    NaN when they have no hip, knee and ankle of one side (or only NaN there)."""
    arr = np.asarray(joints, np.float64)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN frames: NaN
        return _leg({n: arr[:, i] for i, n in enumerate(joint_names)})[0]


def points_units(joints: np.ndarray, joint_names: Any, units: Any = None, up: str | None = None) -> Units:
    """The :class:`Units` of (T, n, 3) points named by model joints (``left_hip``, ``left_knee``, ...), e.g. a
    ``.npy`` of joints: the leg length says the unit, the ankles → hips direction the up axis. Raises ValueError
    when no unit makes a person of them, or the leg cannot be measured (:func:`leg_length` is NaN)."""
    arr = np.asarray(joints, np.float64)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        leg, direction = _leg({n: arr[:, i] for i, n in enumerate(joint_names)})
    return decide_units(leg, None if direction is None else snap_up(direction), units, up, "joints", points=True)
