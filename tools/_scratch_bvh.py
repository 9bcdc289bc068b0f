"""SCRATCH BVH reader for tools/train_pose_prior.py until smplcore.skeletons lands (then deleted)."""

from __future__ import annotations

import gzip
from dataclasses import dataclass

import numpy as np


@dataclass
class Bvh:
    names: list[str]  # joints and end sites ("<parent>_end")
    parents: np.ndarray
    offsets: np.ndarray  # (J, 3)
    channels: list[list[str]]
    frame_time: float
    motion: np.ndarray  # (T, C)


def read_bvh(path: str) -> Bvh:
    opener = gzip.open if str(path).endswith(".gz") else open
    with opener(path, "rt") as f:
        tokens_text = f.read().replace("\r", "")
    head, motion = tokens_text.split("MOTION", 1)
    tok = head.split()
    names, parents, offsets, channels = [], [], [], []
    stack: list[int] = []
    i = 0
    pending = -1
    while i < len(tok):
        t = tok[i]
        if t in ("ROOT", "JOINT"):
            names.append(tok[i + 1])
            parents.append(stack[-1] if stack else -1)
            channels.append([])
            offsets.append(None)
            pending = len(names) - 1
            i += 2
        elif t == "End":
            names.append(names[stack[-1]] + "_end")
            parents.append(stack[-1])
            channels.append([])
            offsets.append(None)
            pending = len(names) - 1
            i += 2
        elif t == "{":
            stack.append(pending)
            i += 1
        elif t == "}":
            stack.pop()
            i += 1
        elif t == "OFFSET":
            offsets[stack[-1]] = [float(v) for v in tok[i + 1 : i + 4]]
            i += 4
        elif t == "CHANNELS":
            n = int(tok[i + 1])
            channels[stack[-1]] = tok[i + 2 : i + 2 + n]
            i += 2 + n
        else:
            i += 1
    lines = [ln for ln in motion.split("\n") if ln.strip()]
    frame_time = float(lines[1].split(":")[1])
    data = np.array([ln.split() for ln in lines[2:]], np.float64)
    return Bvh(names, np.array(parents), np.array(offsets, np.float64), channels, frame_time, data)


def _axis_rot(axis: str, deg: np.ndarray) -> np.ndarray:
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    r = np.zeros(a.shape + (3, 3))
    i = "XYZ".index(axis)
    j, k = (i + 1) % 3, (i + 2) % 3
    r[..., i, i] = 1
    r[..., j, j] = c
    r[..., k, k] = c
    r[..., j, k] = -s
    r[..., k, j] = s
    return r


def world_positions(bvh: Bvh, frames: np.ndarray) -> np.ndarray:
    """(T, J, 3) world positions (file units) of every joint and end site at the given frames."""
    return world_transforms(bvh, frames)[1]


def world_transforms(bvh: Bvh, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T, J, 3, 3) world rotations and (T, J, 3) positions (file units) at the given frames."""
    m = bvh.motion[frames]
    t = len(frames)
    nj = len(bvh.names)
    rot = np.empty((t, nj, 3, 3))
    pos = np.empty((t, nj, 3))
    col = 0
    for j in range(nj):
        local = np.broadcast_to(np.eye(3), (t, 3, 3)).copy()
        trans = np.broadcast_to(bvh.offsets[j], (t, 3)).copy()
        for ch in bvh.channels[j]:
            v = m[:, col]
            col += 1
            if ch.endswith("position"):
                trans[:, "XYZ".index(ch[0])] += v
            else:
                local = local @ _axis_rot(ch[0], v)
        p = bvh.parents[j]
        if p < 0:
            rot[:, j], pos[:, j] = local, trans
        else:
            rot[:, j] = rot[:, p] @ local
            pos[:, j] = pos[:, p] + np.einsum("tij,tj->ti", rot[:, p], trans)
    return rot, pos
