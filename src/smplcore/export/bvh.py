"""Skeleton motion as BVH (Biovision Hierarchy), for motion tools (Blender, MotionBuilder, bvhio, ...).

Layout of the written file:

* ``HIERARCHY``: one ``JOINT`` per model joint, nested as in the model's kinematic tree, named after it.
  ``OFFSET``\\ s are the shaped rest pose's ``joint - parent joint`` (metres by default; ``scale=100``
  writes centimetres). The ``ROOT`` has ``OFFSET 0 0 0`` and six channels
  ``Xposition Yposition Zposition`` + rotations, its position channels holding the *absolute* root
  joint position (rest root joint + ``transl``), so readers that add the root offset and readers that
  ignore it agree. Every other joint has three rotation channels.
* Rotation channels are intrinsic Euler angles in degrees, ``Zrotation Yrotation Xrotation`` by
  default (``euler="ZYX"``: the local rotation is ``Rz @ Ry @ Rx``, the usual BVH reading of channels
  from left to right), computed with :class:`scipy.spatial.transform.Rotation`. Angles are kept
  continuous over time (the equivalent angle triple closest to the previous frame's), so tools that
  interpolate between frames do not spin.
* Leaf joints get an ``End Site`` along their bone, reaching the far end of the mesh part they move
  (top of the head, hand, toe).
* ``MOTION``: ``Frames: T`` and ``Frame Time: 1 / fps``.

Forward kinematics of the file reproduces the model's joints (without translation-dependent extras)
to the printed precision (6 decimals).
"""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.export.animation import Animation, ExportReport, Progress, prepare_animation

__all__ = ["save_bvh", "euler_angles"]

_AXES = {"X", "Y", "Z"}


def _check_order(order: str) -> str:
    order = str(order).upper()
    if len(order) != 3 or set(order) != _AXES:
        raise ValueError(f"euler: expected an order of the three axes such as 'ZYX' or 'ZXY', got {order!r}")
    return order


def euler_angles(rotations: np.ndarray, order: str = "ZYX") -> np.ndarray:
    """(T, J, 3, 3) rotations -> (T, J, 3) intrinsic Euler angles in degrees, in ``order``
    (``R = R_order[0] @ R_order[1] @ R_order[2]``), continuous over time."""
    from scipy.spatial.transform import Rotation

    order = _check_order(order)
    frames, joints = rotations.shape[:2]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # gimbal lock: the angles still give the rotation
        angles = Rotation.from_matrix(rotations.reshape(-1, 3, 3)).as_euler(order, degrees=True)
    angles = angles.reshape(frames, joints, 3)
    # Each rotation has a second triple (a + 180, 180 - b, c + 180); pick per frame the triple closest
    # to the previous frame's, each angle shifted by whole turns to be nearest to its previous value.
    alternate = np.stack([angles[..., 0] + 180.0, 180.0 - angles[..., 1], angles[..., 2] + 180.0], axis=-1)
    out = np.empty_like(angles)
    out[0] = angles[0]
    for t in range(1, frames):
        prev = out[t - 1]
        best = None
        for cand in (angles[t], alternate[t]):
            cand = cand - 360.0 * np.round((cand - prev) / 360.0)
            dist = np.abs(cand - prev).sum(axis=-1)
            if best is None:
                best, best_dist = cand, dist
            else:
                pick = dist < best_dist - 1e-9
                best = np.where(pick[:, None], cand, best)
                best_dist = np.where(pick, dist, best_dist)
        out[t] = best
    return out


def _end_sites(anim: Animation) -> dict[int, np.ndarray]:
    """Offset of the end site of each leaf joint: along the bone from the parent, as far as the vertices
    the joint mostly moves reach (at least a tenth of the bone length)."""
    dominant = np.argmax(anim.weights, axis=1)
    children = {j: np.flatnonzero(anim.parents == j) for j in range(anim.num_joints)}
    out = {}
    for j, kids in children.items():
        if kids.size:
            continue
        parent = anim.parents[j]
        bone = anim.rest_joints[j] - (anim.rest_joints[parent] if parent >= 0 else anim.rest_joints[j] - [0, 0.1, 0])
        length = float(np.linalg.norm(bone))
        direction = bone / length if length > 1e-9 else np.array([0.0, 1.0, 0.0])
        verts = anim.rest_vertices[dominant == j]
        reach = float(((verts - anim.rest_joints[j]) @ direction).max()) if len(verts) else 0.0
        out[j] = direction * max(reach, 0.1 * max(length, 1e-3))
    return out


def save_bvh(
    path: str | Path,
    model: Any,
    source: Any,
    *,
    fps: float | None = None,
    scale: float = 1.0,
    euler: str = "ZYX",
    decimals: int = 6,
    progress: Progress | None = None,
) -> ExportReport:
    """Write ``source`` on ``model`` as a BVH file.

    Parameters
    ----------
    path : the ``.bvh`` to write (parent folders are created).
    model : a :class:`smplcore.BodyModel` (its shaped rest joints give the offsets).
    source : a :class:`~smplcore.motion.Motion`, a motion or parameter file, a dict of parameter arrays,
        or an :class:`~smplcore.export.animation.Animation`.
    fps : frame rate (default: the motion's, 30 for parameter sets); ``Frame Time`` is ``1 / fps``.
    scale : length unit multiplier: 1 writes metres (default), 100 centimetres.
    euler : rotation channel order, intrinsic (default ``"ZYX"``: ``Zrotation Yrotation Xrotation``).
    decimals : digits after the decimal point for offsets, positions and angles.
    progress : called with numbers of frames processed.
    """
    order = _check_order(euler)
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale: expected a positive number, got {scale!r}")
    path = Path(path)
    if path.suffix.lower() != ".bvh":
        raise ValueError(f"path: expected a .bvh file, got {str(path)!r}")
    anim = source if isinstance(source, Animation) else prepare_animation(model, source, fps=fps, progress=progress)
    if fps is not None and isinstance(source, Animation):
        anim = dataclasses.replace(anim, fps=float(fps))
    notes = list(anim.notes)
    names = [_bvh_name(n) for n in anim.joint_names]
    offsets = anim.offsets * scale
    offsets[0] = 0.0
    ends = {j: v * scale for j, v in _end_sites(anim).items()}
    channels = " ".join(f"{axis}rotation" for axis in order)
    fmt = f"{{:.{decimals}f}}"
    tiny = 0.5 * 10.0**-decimals
    offsets[np.abs(offsets) < tiny] = 0.0
    ends = {j: np.where(np.abs(v) < tiny, 0.0, v) for j, v in ends.items()}

    lines = ["HIERARCHY"]
    visited: list[int] = []  # joints in the order their channels appear (depth first)

    def write_joint(j: int, depth: int) -> None:
        visited.append(j)
        pad = "\t" * depth
        lines.append(f"{pad}{'ROOT' if j == 0 else 'JOINT'} {names[j]}")
        lines.append(pad + "{")
        lines.append(f"{pad}\tOFFSET " + " ".join(fmt.format(v) for v in offsets[j]))
        if j == 0:
            lines.append(f"{pad}\tCHANNELS 6 Xposition Yposition Zposition {channels}")
        else:
            lines.append(f"{pad}\tCHANNELS 3 {channels}")
        kids = np.flatnonzero(anim.parents == j)
        for child in kids:
            write_joint(int(child), depth + 1)
        if not kids.size:
            lines.append(f"{pad}\tEnd Site")
            lines.append(f"{pad}\t{{")
            lines.append(f"{pad}\t\tOFFSET " + " ".join(fmt.format(v) for v in ends[j]))
            lines.append(f"{pad}\t}}")
        lines.append(pad + "}")

    write_joint(0, 0)
    angles = euler_angles(anim.rotations, order)  # (T, J, 3), in `order`
    frames = anim.num_frames
    data = np.concatenate([anim.root_positions * scale, angles[:, visited].reshape(frames, -1)], axis=1)
    data[np.abs(data) < tiny] = 0.0  # no "-0.000000"
    lines += ["MOTION", f"Frames: {frames}", f"Frame Time: {1.0 / anim.fps:.8f}"]
    path.parent.mkdir(parents=True, exist_ok=True)
    row_fmt = " ".join([f"%.{decimals}f"] * data.shape[1])
    with path.open("w", encoding="utf-8", newline="\n") as fh:
        fh.write("\n".join(lines) + "\n")
        for start in range(0, frames, 1024):
            stop = min(start + 1024, frames)
            fh.write("\n".join(row_fmt % tuple(row) for row in data[start:stop]) + "\n")
            if progress is not None:
                progress(stop - start)
    return ExportReport(
        path=path,
        format="bvh",
        num_frames=frames,
        fps=anim.fps,
        num_joints=anim.num_joints,
        file_size=path.stat().st_size,
        warnings=notes,
    )


def _bvh_name(name: str) -> str:
    cleaned = "".join(c if (c.isalnum() or c in "_-.") else "_" for c in str(name))
    return cleaned or "joint"
