"""The 2D inputs of ``smplcore fit``: OpenPose sequences and COCO keypoint files, fitted per person.

* **COCO**: every annotated person of every image is a body of its own, with its own shape (``betas`` is
  then (N, B), one row per body, beside ``image_id`` and ``person``); the people of one image share its
  camera.
* **OpenPose**: the people of each frame are followed over the sequence (:func:`smplcore.fit.tracks.
  track_people`); each track is one person, fitted with one shape over its frames. ``person`` picks a track
  (0, the default, is the person seen in the most frames; frames without that person get the nearest
  frame's fit), or ``"all"`` fits every track: the output then has a row per (track, frame) seen, with
  ``track`` and ``frame`` and one shape per row (each track's own).

Keypoints outside the image (when its size is known) do not pull on the bodies (:mod:`smplcore.fit.
visibility`). With ``settings.overlay`` the fit of the first image (COCO) or frame (OpenPose) is drawn over
``settings.image`` (or a blank canvas of the image's size) through its camera (:mod:`smplcore.render.
overlay`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


@dataclass
class KeypointFit:
    """What :func:`fit_2d` found: parameters and per-row errors, flags, focal lengths and cameras; row labels
    (``image_id``/``person`` or ``track``/``frame``) or None; images without anyone; whether the rows are
    different people (one shape per row); how many people were tracked."""

    params: dict[str, np.ndarray]
    error: np.ndarray
    converged: np.ndarray
    focal: np.ndarray
    intrinsics: np.ndarray
    extrinsics: np.ndarray
    labels: dict[str, np.ndarray] | None = None
    unseen: list[str] = field(default_factory=list)
    people: bool = False
    tracks: int = 0
    keypoints: np.ndarray | None = None  # (rows, K, 3) what was fitted (for the overlay)
    sizes: list[tuple[float, float] | None] = field(default_factory=list)  # per row, the image size if known


def _fits(model, jobs, convention, settings, extra):
    """``jobs``: (rows, keypoints, camera, estimate focal, one person); fitted with fit_keypoints."""
    from smplcore import fit
    from smplcore.fit.inputs import _priors

    up = None if settings.extrinsics is None else np.array([0.0, 1.0, 0.0])  # a given world is Y up
    results = []
    for rows, points, cam, estimate, one in jobs:
        options: dict[str, Any] = dict(share_betas=True, smoothness=settings.smoothness) if one else {}
        r = fit.fit_keypoints(model, points, convention, cam, estimate_focal=estimate, up=up, **options,
                              **_priors(settings), **extra)  # fmt: skip
        results.append((rows, r))
    return results


def _openpose_jobs(path, points, settings) -> tuple[list, int, dict | None, int]:
    """The fits of an OpenPose sequence: jobs, rows, labels, tracks found."""
    from smplcore.fit.inputs import _camera
    from smplcore.fit.tracks import track_people

    tracks = track_people(points)
    if tracks.shape[1] == 0:
        raise ValueError(f"keypoints: no frame of {path} shows a person with 6 keypoints of confidence 0.1")
    seen = (tracks[..., 2] >= 0.1).sum(-1) >= 6  # (T, N)
    cam, estimate = _camera(settings)
    if settings.person == "all":
        jobs, start, frames, which = [], 0, [], []
        for n in range(tracks.shape[1]):
            t = np.flatnonzero(seen[:, n])
            jobs.append((start + np.arange(len(t)), tracks[t, n], cam, estimate, True))
            start += len(t)
            frames.append(t)
            which.append(np.full(len(t), n))
        labels = {"track": np.concatenate(which), "frame": np.concatenate(frames)}
        return jobs, start, labels, tracks.shape[1]
    person = int(settings.person)
    if person >= tracks.shape[1]:
        raise ValueError(
            f"--person: {path} shows {tracks.shape[1]} people (tracks 0 to {tracks.shape[1] - 1}, the longest first)"
        )
    t = np.flatnonzero(seen[:, person])
    return [(t, tracks[t, person], cam, estimate, True)], len(tracks), None, tracks.shape[1]


def fit_2d(path: Path, kind: str, settings: Any, model: Any, extra: dict[str, Any]) -> KeypointFit:
    """Fit an OpenPose folder or a COCO file (see the module docstring)."""
    from smplcore import keypoints as kp
    from smplcore.fit.inputs import _camera, _coco_image_sizes, _gather, _ground, _matrices

    array = kp.read_openpose(path) if kind == "openpose" else kp.read_coco(path)
    convention = settings.convention or array.convention
    if convention is None:
        raise ValueError(f"--convention: cannot tell the keypoints' convention in {path}; give it")
    points = array.points.astype(np.float64)
    labels, unseen, tracks = None, [], 0
    if kind == "openpose":
        jobs, count, labels, tracks = _openpose_jobs(path, points, settings)
        sizes: list = [settings.image_size] * count
    else:
        points[..., 2] = (points[..., 2] > 0).astype(np.float64)  # COCO visibility → confidence
        frame, person = np.nonzero(points[..., 2].sum(-1) >= 6)
        if len(frame) == 0:
            raise ValueError(f"keypoints: no person in {path} has 6 or more labelled keypoints")
        known = _coco_image_sizes(path) if settings.image_size is None else {}
        jobs, sizes = [], [None] * len(frame)
        for f in np.unique(frame):  # one camera per image
            rows = np.flatnonzero(frame == f)
            size = settings.image_size or known.get(array.frames[f])
            cam, estimate = _camera(settings, size)
            jobs.append((rows, points[f, person[rows]], cam, estimate, False))
            for row in rows:
                sizes[row] = size
        labels = {"image_id": np.array([str(array.frames[f]) for f in frame]), "person": person}
        count = len(frame)
        # images with nobody to fit are not in the output: the summary names them
        unseen = [str(array.frames[f]) for f in sorted(set(range(len(array.frames))) - set(frame.tolist()))]
    results = _fits(model, jobs, convention, settings, extra)
    error: np.ndarray = np.full(count, np.nan)  # frames without the person: NaN, not converged, nearest frame's fit
    converged = np.zeros(count, bool)
    focal = np.full((count, 2), np.nan)
    intrinsics, extrinsics = np.tile(np.eye(3), (count, 1, 1)), np.tile(np.eye(4), (count, 1, 1))
    fitted_points = np.zeros((count, *jobs[0][1].shape[1:]))
    parts: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    for (rows, r), job in zip(results, jobs, strict=True):
        error[rows] = r.reprojection_error
        converged[rows] = r.converged
        focal[rows] = r.camera.focal
        intrinsics[rows], extrinsics[rows] = _matrices(r.camera)
        fitted_points[rows] = job[1]
        for key, value in r.params.items():
            parts.setdefault(key, []).append((rows, np.asarray(value)))
    params = {k: _gather(v, count) for k, v in parts.items()}
    fitted = np.concatenate([rows for rows, _ in results])
    if len(fitted) < count:
        nearest = fitted[np.abs(np.arange(count)[:, None] - fitted[None]).argmin(1)]
        params = {k: v[nearest] for k, v in params.items()}
        focal, intrinsics, extrinsics = focal[nearest], intrinsics[nearest], extrinsics[nearest]
    if settings.extrinsics is None:  # the level camera's world: feet on the ground, per camera
        groups = [np.arange(count)] if kind == "openpose" else [rows for rows, _ in results]
        for rows in groups:
            _ground(model, params, extrinsics, rows)
    people = kind == "coco" or settings.person == "all"
    return KeypointFit(
        params, error, converged, focal, intrinsics, extrinsics, labels, unseen,
        people=people and len(np.unique(params["betas"], axis=0)) > 1, tracks=tracks,
        keypoints=fitted_points, sizes=sizes,
    )  # fmt: skip


def check_overlay(overlay: Path | None, image: Path | None, single: bool) -> None:
    """``--overlay`` / ``--image`` that cannot work, refused (ValueError) before any fit."""
    if overlay is None:
        if image is not None:
            raise ValueError("--image: the photo is for --overlay out.png; add it (or drop --image)")
        return
    if not single:
        raise ValueError("--overlay: draws one input's fit; give one OpenPose folder or COCO file, not a batch")
    if overlay.suffix.lower() != ".png":
        raise ValueError(f"--overlay: expected a .png file, got {overlay}")
    if image is not None and not image.is_file():
        raise ValueError(f"--image: {image}: no such file")


def write_overlay(model: Any, found: KeypointFit, settings: Any) -> Path:
    """Draw the fit of the first image (COCO) or frame (OpenPose) over ``settings.image`` (or a blank canvas
    of its size) to ``settings.overlay``; returns the path."""
    from smplcore.fit.camera import Camera
    from smplcore.render import save_overlay

    labels = found.labels or {}
    key = "image_id" if "image_id" in labels else "frame" if "frame" in labels else None
    if key is not None:
        rows = np.flatnonzero(labels[key] == labels[key][0])
    else:  # one person: the first frame it is seen in
        rows = np.flatnonzero(np.isfinite(found.error))[:1]
    k, e = found.intrinsics[rows[0]], found.extrinsics[rows[0]]
    size = found.sizes[rows[0]] if found.sizes else None
    if size is None and settings.image is None:
        raise ValueError("--overlay: the image's size is unknown; give --image (the photo) or --image-size W,H")
    camera = Camera(focal=np.diag(k)[:2], center=k[:2, 2], rotation=e[:3, :3], translation=e[:3, 3], image_size=size)
    params = {name: np.asarray(value)[rows] for name, value in found.params.items()}
    vertices = np.asarray(model(**params).vertices)
    kps = None if found.keypoints is None else found.keypoints[rows]
    return save_overlay(settings.overlay, settings.image, vertices, model.faces, camera, keypoints=kps)
