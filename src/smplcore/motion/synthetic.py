"""Synthetic AMASS-style sequences, for tests, benchmarks and trying the pipeline without data.

The poses are smooth (a few sinusoids per joint axis, about ±0.4 rad), the body walks forward,
and the files have AMASS's keys: SMPL+H ``poses`` (T, 156), ``trans``, ``betas`` (16), ``gender``,
``mocap_framerate``, ``dmpls`` (T, 8); SMPL-X ``poses`` (T, 165), ``trans``, ``betas`` (16),
``gender``, ``mocap_frame_rate``, ``surface_model_type``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from smplcore.motion.sequence import POSE_WIDTH


def random_arrays(
    frames: int, fps: float = 120.0, model_type: str = "smplh", gender: str = "female", seed: int = 0
) -> dict[str, np.ndarray]:
    """The arrays of one AMASS-style file (what ``np.savez`` would store)."""
    rng = np.random.default_rng(seed)
    width = POSE_WIDTH[model_type]
    t = np.arange(frames)[:, None] / fps
    poses = np.zeros((frames, width))
    for _ in range(3):
        freq = rng.uniform(0.2, 2.0, size=(1, width))
        phase = rng.uniform(0, 2 * np.pi, size=(1, width))
        poses += rng.uniform(0.0, 0.15, size=(1, width)) * np.sin(2 * np.pi * freq * t + phase)
    poses[:, :3] += np.array([np.pi / 2, 0.0, 0.0])  # AMASS bodies are Z-up: root turned about X
    trans = np.concatenate([0.8 * t, 0.05 * np.sin(3 * t), 0.9 + 0.02 * np.sin(6 * t)], axis=1)
    out = {"poses": poses, "trans": trans, "betas": rng.normal(0, 1, 16), "gender": np.array(gender)}
    if model_type == "smplx":
        out["mocap_frame_rate"] = np.array(float(fps))
        out["surface_model_type"] = np.array("smplx")
    else:
        out["mocap_framerate"] = np.array(float(fps))
        out["dmpls"] = rng.normal(0, 0.1, (frames, 8))
    return out


def write_sequence(
    path: str | Path,
    frames: int,
    fps: float = 120.0,
    model_type: str = "smplh",
    gender: str = "female",
    seed: int = 0,
) -> Path:
    """Write one synthetic AMASS-style ``.npz``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays: dict[str, Any] = random_arrays(frames, fps, model_type, gender, seed)
    np.savez(path, **arrays)
    return path


def write_tree(
    root: str | Path, sequences: list[tuple[str, int, float, str]], model_type: str = "smplh", seed: int = 0
) -> list[Path]:
    """Write ``(relative path, frames, fps, gender)`` sequences under ``root``; return their paths."""
    return [
        write_sequence(Path(root) / rel, frames, fps, model_type, gender, seed + i)
        for i, (rel, frames, fps, gender) in enumerate(sequences)
    ]
