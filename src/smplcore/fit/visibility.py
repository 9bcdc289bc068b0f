"""What a 2D fit uses of its keypoints, and what the image shows of each body.

A keypoint pulls on the body when the detector is confident of it (``confidence >= min_confidence``, then
weighted by its confidence), when the model has it, and when it lies inside the image (a
:class:`~smplcore.fit.Camera` with an ``image_size``): detectors such as MediaPipe extrapolate the parts an
image cuts off, with a visibility that is often still high, and such guesses would pull the body (shrunk
towards the image's edge, it is placed too far away). Keypoints that do not pull are left to the priors.

A body whose knees, ankles and feet are all unused has no legs in the image (an upper-body photo, a person
cut at the hips): the legs are then the priors' (standing, as in the rest pose) and the body's tilt the
upright prior's (:mod:`smplcore.fit.reprojection`), and :func:`warn_unseen` says so
(:class:`PartialViewWarning`).
"""

from __future__ import annotations

import numpy as np

from smplcore.errors import warn
from smplcore.fit.camera import Camera

#: Keypoints (by name, in any convention) that show the legs below the hips.
LEGS = (
    "left_knee", "right_knee", "left_ankle", "right_ankle", "left_heel", "right_heel", "left_big_toe",
    "right_big_toe", "left_small_toe", "right_small_toe", "left_foot", "right_foot", "left_foot_index",
    "right_foot_index",
)  # fmt: skip
#: Keypoints at the hips.
HIPS = ("left_hip", "right_hip", "mid_hip", "pelvis")
#: Pixels inside the image's edges a keypoint must be to count as seen (detectors clamp guesses to the edge).
EDGE_MARGIN = 1.0


class PartialViewWarning(UserWarning):
    """A 2D fit's bodies lack keypoints for whole parts (legs out of the image): those parts are the priors'."""


def keypoint_weights(
    targets: np.ndarray, confidence: np.ndarray, available: np.ndarray, camera: Camera, min_confidence: float
) -> tuple[np.ndarray, np.ndarray]:
    """The weights (B, K) of the keypoints (their confidence where used, else 0) and (B, K) which ones lie
    outside the image (all False when the camera's image size is unknown).

    ``targets`` (B, K, 2) pixels, ``confidence`` (B, K), ``available`` (K,) the keypoints the model has.
    """
    outside = ~camera.inside(targets, EDGE_MARGIN)
    used = (confidence >= min_confidence) & available & ~outside
    return np.where(used, confidence, 0.0), outside & (confidence >= min_confidence)


def legs_seen(names: tuple[str, ...] | list[str], weights: np.ndarray) -> np.ndarray:
    """(B,) whether any keypoint below the hips is used; True for conventions without leg keypoints."""
    legs = np.array([n in LEGS for n in names])
    if not legs.any():
        return np.ones(len(weights), bool)
    return np.asarray((weights[:, legs] > 0).any(axis=1))


def warn_unseen(names: tuple[str, ...] | list[str], weights: np.ndarray, outside: np.ndarray, what: str) -> np.ndarray:
    """Warn (once) about the bodies whose legs are not seen; returns (B,) whether the legs are seen."""
    seen = legs_seen(names, weights)
    if seen.all():
        return seen
    bad = np.flatnonzero(~seen)
    legs = np.array([n in LEGS for n in names])
    cut = bool(outside[np.ix_(bad, np.flatnonzero(legs))].any())
    why = "outside the image or below the confidence threshold" if cut else "below the confidence threshold"
    warn(
        f"{what}: legs not visible in {len(bad)} of {len(weights)} bodies (body {int(bad[0])}: no knee, ankle "
        f"or foot keypoint used, {why}); their legs are the prior's (standing) and their tilt the upright "
        "prior's: what is below the hips is a guess, not a fit",
        PartialViewWarning,
    )
    return seen


def weighted_error(distances: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(B,) confidence-weighted mean of (B, K) pixel distances over the keypoints used (weights > 0)."""
    total = weights.sum(axis=1)
    return (distances * weights).sum(axis=1) / np.maximum(total, 1e-300)
