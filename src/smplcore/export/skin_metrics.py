"""Skinning helpers of the exporters: the top-k weights a rig carries, its linear blend skinning, and how far
the written skin is from the model (weight truncation; pose correctives a rig cannot express)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from smplcore.engine import pose_features, skin

if TYPE_CHECKING:
    from smplcore.export.animation import Animation, Progress

#: Frames posed per step (exporters and metrics alike): bounded memory for long motions.
FRAMES_PER_CHUNK = 256

__all__ = ["FRAMES_PER_CHUNK", "lbs", "pose_corrective_error", "top_k_weights", "truncation_error"]


def top_k_weights(weights: np.ndarray, k: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ``k`` largest weights of each vertex, renormalised to sum to one.

    Returns
    -------
    joints : (V, k) joint indices, largest weight first; unused slots (weight 0) hold joint 0.
    values : (V, k) float64 weights summing to one per vertex.
    dropped : (V,) weight mass removed before renormalising.
    """
    w = np.clip(np.asarray(weights, dtype=np.float64), 0.0, None)
    order = np.argsort(-w, axis=1, kind="stable")[:, :k]
    values = np.take_along_axis(w, order, axis=1)
    total = w.sum(axis=1)
    kept = values.sum(axis=1)
    if np.any(kept <= 0):
        raise ValueError(f"weights: {int(np.sum(kept <= 0))} vertices have no skinning weight")
    values = values / kept[:, None]
    joints = np.where(values > 0, order, 0)
    return joints.astype(np.int64), values, total - kept


def _weight_matrix(joints: np.ndarray, values: np.ndarray, num_joints: int) -> np.ndarray:
    out = np.zeros((joints.shape[0], num_joints))
    np.add.at(out, (np.repeat(np.arange(joints.shape[0]), joints.shape[1]), joints.reshape(-1)), values.reshape(-1))
    return out


def _engine_transforms(matrices: np.ndarray) -> np.ndarray:
    """(T, J, 3, 4) matrices as the engine's (T, J, 12) skinning transforms (rotation rows, then translation)."""
    frames, joints = matrices.shape[:2]
    return np.concatenate([matrices[..., :3].reshape(frames, joints, 9), matrices[..., 3]], axis=-1)


def lbs(vertices: np.ndarray, matrices: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Linear blend skinning of rest ``vertices`` (V, 3) with (T, J, 3, 4) ``matrices`` and (V, J)
    ``weights``: (T, V, 3). The engine's skinning (:func:`smplcore.engine.skin`), one rest mesh for
    every frame."""
    matrices = np.asarray(matrices)
    vertices = np.asarray(vertices, dtype=matrices.dtype)
    rest = np.broadcast_to(vertices.T, (matrices.shape[0],) + vertices.T.shape)  # (T, 3, V), no copy
    return skin(rest, _engine_transforms(matrices), np.asarray(weights, dtype=matrices.dtype).T)


def truncation_error(
    anim: Animation, joints: np.ndarray, values: np.ndarray, progress: Progress | None = None
) -> dict[str, float | int]:
    """How far vertices move when skinned with the truncated weights instead of the full ones, over
    every frame of ``anim``: ``max``, ``mean`` (over all vertices and frames, metres), ``affected``
    (vertices that lost weight) and ``max_dropped`` (largest weight mass removed)."""
    full = anim.weights / anim.weights.sum(axis=1, keepdims=True)
    kept = _weight_matrix(joints, values, anim.num_joints)
    delta = full - kept
    affected = np.flatnonzero(np.abs(delta).max(axis=1) > 1e-12)
    stats = {
        "max": 0.0,
        "mean": 0.0,
        "affected": int(affected.size),
        "max_dropped": float(np.clip(delta, 0, None).sum(axis=1).max()),
    }
    if affected.size == 0:
        if progress is not None:
            progress(anim.num_frames)
        return stats
    verts = anim.rest_vertices[affected]
    total, worst = 0.0, 0.0
    for start in range(0, anim.num_frames, FRAMES_PER_CHUNK):
        stop = min(start + FRAMES_PER_CHUNK, anim.num_frames)
        mats = anim.skinning_matrices(slice(start, stop))
        diff = np.linalg.norm(lbs(verts, mats, delta[affected]), axis=-1)  # translations cancel: rows sum to 0
        total += float(diff.sum())
        worst = max(worst, float(diff.max()))
        if progress is not None:
            progress(stop - start)
    stats["max"] = worst
    stats["mean"] = total / (anim.num_frames * anim.rest_vertices.shape[0])
    return stats


def pose_corrective_error(model: Any, anim: Animation) -> float | None:
    """Largest vertex displacement the model's pose correctives cause over the frames of ``anim``
    (None when the model has none): what a rig without them cannot show."""
    rig = model.rig
    if not rig.has_pose_correctives:
        return None
    basis = rig.posedirs.reshape(rig.posedirs.shape[0], -1)  # (P, V * 3)
    worst = 0.0
    weights_t = np.ascontiguousarray(anim.weights.T)
    for start in range(0, anim.num_frames, 64):
        stop = min(start + 64, anim.num_frames)
        offsets = (pose_features(anim.rotations[start:stop]) @ basis).reshape(stop - start, -1, 3)
        world_rot, _ = anim.world_transforms(slice(start, stop))
        # the offsets are directions: skinned by the joints' world rotations alone (no translation)
        rotation_only = np.concatenate(
            [world_rot.reshape(stop - start, -1, 9), np.zeros(world_rot.shape[:2] + (3,))], -1
        )
        moved = skin(np.swapaxes(offsets, 1, 2), rotation_only, weights_t)
        worst = max(worst, float(np.linalg.norm(moved, axis=-1).max()))
    return worst
