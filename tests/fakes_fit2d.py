"""Synthetic 2D keypoint scenes for the fitting tests: open-model bodies in front of a known camera,
written as OpenPose or COCO files, and a fake SMPLify GMM file (seeded random data with the official
file's structure)."""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import numpy as np

from smplcore import fit
from smplcore import keypoints as kp

CAMERA = fit.Camera(focal=1000.0, center=(500.0, 500.0))


def _col(names, joint: str, axis: int) -> int:
    return (names.index(joint) - 1) * 3 + axis


def natural_poses(model, batch: int, rng: np.random.Generator, spread: float = 0.1) -> dict[str, np.ndarray]:
    """Body poses with knees and elbows bent the right way, arms lowered, facing the camera (±15°)."""
    names = list(model.joint_names)
    pose = rng.normal(0, spread, (batch, 69))
    for side, s in (("left", 1.0), ("right", -1.0)):
        pose[:, _col(names, f"{side}_knee", 0)] = rng.uniform(0.1, 1.0, batch)
        pose[:, _col(names, f"{side}_elbow", 1)] = -s * rng.uniform(0.2, 1.3, batch)
        pose[:, _col(names, f"{side}_shoulder", 2)] = -s * rng.uniform(0.3, 1.1, batch)
    return {
        "global_orient": np.tile([np.pi, 0.0, 0.0], (batch, 1)) + rng.normal(0, 0.25, (batch, 3)),
        "body_pose": pose,
        "betas": rng.normal(0, 0.5, (batch, 10)),
        "transl": np.c_[rng.normal(0, 0.3, batch), rng.normal(0, 0.2, batch), rng.uniform(3.0, 5.0, batch)],
    }


def scene(model, params, rng, noise: float = 1.0, convention: str = "coco17", camera=CAMERA):
    """(B, K, 3) noisy keypoints (confidence 1), the exact pixels (B, K, 2) and the 3D keypoints (B, K, 3)."""
    joints = np.asarray(model(**params).joints, np.float64)
    j3 = kp.convert(joints, model, convention)[0]
    exact = camera.project(j3)
    noisy = exact + rng.normal(0, noise, exact.shape)
    return np.concatenate([noisy, np.ones(noisy.shape[:2] + (1,))], -1), exact, j3


def write_openpose(folder: Path, keypoints: np.ndarray) -> Path:
    """One OpenPose JSON file per frame of ``keypoints`` (T, 25, 3), one person each, named as OpenPose
    names them (``*_keypoints.json``)."""
    folder.mkdir(parents=True)
    for t, frame in enumerate(keypoints):
        doc = {"version": 1.3, "people": [{"pose_keypoints_2d": np.asarray(frame).reshape(-1).tolist()}]}
        (folder / f"frame_{t:04d}_keypoints.json").write_text(json.dumps(doc))
    return folder


def write_coco(path: Path, keypoints: np.ndarray, width: int, height: int, image_id: int = 1) -> Path:
    """A COCO keypoint file: the people ``keypoints`` (B, 17, 2 or 3) in one image of ``width`` x ``height``,
    every point labelled and visible (v = 2)."""
    points = np.asarray(keypoints)[..., :2]
    annotations = [
        {"id": i + 1, "image_id": image_id, "category_id": 1, "num_keypoints": 17,
         "keypoints": np.c_[person, np.full(len(person), 2)].reshape(-1).tolist()}
        for i, person in enumerate(points)
    ]  # fmt: skip
    doc = {
        "images": [{"id": image_id, "file_name": f"{image_id:012d}.jpg", "width": width, "height": height}],
        "annotations": annotations,
        "categories": [{"id": 1, "name": "person"}],
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc))
    return path


def pa_mpjpe(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(B,) mean distance after the similarity (Procrustes) alignment of ``b`` (B, n, 3) to ``a``."""
    out = []
    for x, y in zip(a, b, strict=True):
        x0, y0 = x - x.mean(0), y - y.mean(0)
        u, s, vt = np.linalg.svd(y0.T @ x0)
        d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
        rot = u @ d @ vt
        scale = np.sum(s * np.diag(d)) / np.sum(y0 * y0)
        out.append(np.linalg.norm(scale * y0 @ rot - x0, axis=1).mean())
    return np.asarray(out)


def write_fake_gmm(path: Path, dim: int = 69, components: int = 8, seed: int = 0) -> Path:
    """A pickle with SMPLify's gmm_08.pkl layout: means (8, 69), covars (8, 69, 69), weights (8,)."""
    rng = np.random.default_rng(seed)
    a = rng.normal(0, 0.1, (components, dim, dim))
    covars = a @ np.swapaxes(a, 1, 2) / dim + 0.02 * np.eye(dim)
    data = {
        "means": rng.normal(0, 0.1, (components, dim)),
        "covars": covars,
        "weights": rng.dirichlet(np.ones(components)),
    }
    with open(path, "wb") as fh:
        pickle.dump(data, fh, protocol=2)
    return path
