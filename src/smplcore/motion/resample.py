"""Changing the frame rate of a motion: stride (HumanML3D), nearest frame, or interpolation.

Three methods, all returning the frames as positions in the source sequence:

``stride``
    Keep every ``int(fps / target)``-th frame, as HumanML3D does (``poses[::down_sample]``). The
    result's rate is ``fps / step``, which equals the target only when it divides the source rate
    (120 → 20, 60 → 20) and differs otherwise (59.94 → 29.97). A source slower than the target
    keeps every frame.
``nearest``
    Frames at exactly ``k / target`` seconds, each taken from the nearest source frame (ties go to
    the earlier one); exact target rate, no new poses.
``interp``
    Frames at exactly ``k / target`` seconds, rotations interpolated by spherical linear
    interpolation (per joint, shortest arc), translations, DMPLs and expressions linearly. A
    resampled frame that falls on a source frame is that frame, bit for bit.

The resampled sequence covers ``[0, duration of the source]``: the last frame is at or before the
source's last frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from smplcore.engine.rotations import quat_to_rotvec, rotvec_to_quat

METHODS = ("interp", "nearest", "stride")


@dataclass(frozen=True)
class ResamplePlan:
    """Where each resampled frame comes from.

    Attributes
    ----------
    index : (N,) source frame at or before each new frame.
    weight : (N,) weight of frame ``index + 1`` (0 = exactly frame ``index``).
    fps : the new frame rate.
    """

    index: np.ndarray
    weight: np.ndarray
    fps: float

    @property
    def num_frames(self) -> int:
        return int(self.index.shape[0])

    @property
    def source_position(self) -> np.ndarray:
        """(N,) position of each new frame in source frames (fractional for interpolated frames)."""
        return self.index + self.weight

    @property
    def is_selection(self) -> bool:
        """Every new frame is a source frame (no interpolation needed)."""
        return not np.any(self.weight)


def plan(num_frames: int, fps: float, target_fps: float, method: str = "interp") -> ResamplePlan:
    """The source frames of a ``num_frames``-frame sequence at ``fps`` resampled to ``target_fps``."""
    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    for name, value in (("fps", fps), ("target_fps", target_fps)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{name}: expected a positive frame rate, got {value}")
    if num_frames <= 0:
        return ResamplePlan(np.zeros(0, np.int64), np.zeros(0), float(target_fps))
    if method == "stride":
        step = max(1, int(fps / target_fps))
        index = np.arange(0, num_frames, step, dtype=np.int64)
        return ResamplePlan(index, np.zeros(index.shape), float(fps) / step)
    # New frame k sits at source position k * fps / target; keep those within the source.
    ratio = float(fps) / float(target_fps)
    count = int(math.floor((num_frames - 1) / ratio + 1e-9)) + 1
    position = np.arange(count, dtype=np.float64) * ratio
    if method == "nearest":
        index = np.minimum(np.floor(position + 0.5 - 1e-9), num_frames - 1).astype(np.int64)
        return ResamplePlan(index, np.zeros(count), float(target_fps))
    index = np.minimum(np.floor(position + 1e-9), num_frames - 1).astype(np.int64)
    weight = np.clip(position - index, 0.0, 1.0)
    weight[np.abs(weight) < 1e-9] = 0.0
    weight[index == num_frames - 1] = 0.0
    return ResamplePlan(index, weight, float(target_fps))


def apply_linear(values: np.ndarray, p: ResamplePlan) -> np.ndarray:
    """``values`` (T, ...) at the planned frames, interpolated linearly."""
    values = np.asarray(values)
    out = values[p.index]
    if p.is_selection:
        return out
    mix = p.weight > 0
    nxt = values[np.minimum(p.index[mix] + 1, values.shape[0] - 1)]
    w = p.weight[mix].reshape((-1,) + (1,) * (values.ndim - 1))
    out = out.astype(np.result_type(values.dtype, np.float64), copy=True)
    out[mix] = (1 - w) * out[mix] + w * nxt
    return out


def apply_rotations(poses: np.ndarray, p: ResamplePlan) -> np.ndarray:
    """Axis-angle poses (T, 3 J) at the planned frames, each joint interpolated by slerp."""
    poses = np.asarray(poses)
    out = poses[p.index]
    if p.is_selection:
        return out
    mix = p.weight > 0
    frames = int(mix.sum())
    a = poses[p.index[mix]].reshape(frames, -1, 3)
    b = poses[np.minimum(p.index[mix] + 1, poses.shape[0] - 1)].reshape(frames, -1, 3)
    out = out.astype(np.float64, copy=True)
    out[mix] = slerp_rotvec(a, b, p.weight[mix][:, None]).reshape(frames, -1)
    return out


def slerp_rotvec(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Spherical linear interpolation between axis-angle rotations ``a`` and ``b`` (…, 3) at ``t``."""
    qa, qb = rotvec_to_quat(a), rotvec_to_quat(b)
    dot = np.sum(qa * qb, axis=-1, keepdims=True)
    qb = np.where(dot < 0, -qb, qb)
    dot = np.abs(dot)
    t = np.asarray(t, dtype=np.float64)[..., None]
    close = dot > 0.9995
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_theta = np.where(close, 1.0, np.sin(theta))
    wa = np.where(close, 1 - t, np.sin((1 - t) * theta) / sin_theta)
    wb = np.where(close, t, np.sin(t * theta) / sin_theta)
    q = wa * qa + wb * qb
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return quat_to_rotvec(q)
