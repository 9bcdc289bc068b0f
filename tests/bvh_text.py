"""BVH text built in code for the skeleton tests, with an independent forward kinematics (axis matrices
multiplied by hand, no scipy) to check the reader against."""

from __future__ import annotations

import numpy as np


def axis_matrix(axis: str, degrees: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations about ``axis`` by ``degrees``."""
    a = np.radians(degrees)
    c, s = np.cos(a), np.sin(a)
    one, zero = np.ones_like(a), np.zeros_like(a)
    rows = {
        "X": [[one, zero, zero], [zero, c, -s], [zero, s, c]],
        "Y": [[c, zero, s], [zero, one, zero], [-s, zero, c]],
        "Z": [[c, -s, zero], [s, c, zero], [zero, zero, one]],
    }[axis]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def bvh_text(
    names: list[str],
    parents: list[int],
    offsets: np.ndarray,
    orders: list[str],
    angles: list[np.ndarray],
    root_positions: np.ndarray,
    *,
    end_sites: dict[int, tuple[float, float, float]] | None = None,
    frame_time: str = "0.0333333",
    newline: str = "\n",
    indent: str = "\t",
    number: str = "{:.6f}",
) -> str:
    """The BVH text of a skeleton whose joints are listed parents first (depth first, as BVH nests them).

    ``orders[j]`` is joint j's rotation channel order (``"ZXY"``, ``"XY"``, ``""``); ``angles[j]`` its (T, len)
    angles in degrees; the root also gets ``Xposition Yposition Zposition`` first.
    """
    end_sites = end_sites or {}
    children: dict[int, list[int]] = {}
    for j, p in enumerate(parents):
        children.setdefault(p, []).append(j)
    lines = ["HIERARCHY"]
    order_written: list[int] = []

    def joint(j: int, depth: int) -> None:
        order_written.append(j)
        pad = indent * depth
        lines.append(f"{pad}{'ROOT' if parents[j] < 0 else 'JOINT'} {names[j]}")
        lines.append(pad + "{")
        lines.append(f"{pad}{indent}OFFSET " + " ".join(number.format(v) for v in offsets[j]))
        chans = ([f"{a}position" for a in "XYZ"] if parents[j] < 0 else []) + [f"{a}rotation" for a in orders[j]]
        if chans:
            lines.append(f"{pad}{indent}CHANNELS {len(chans)} " + " ".join(chans))
        for c in children.get(j, []):
            joint(c, depth + 1)
        if j in end_sites:
            lines.extend([f"{pad}{indent}End Site", f"{pad}{indent}{{",
                      f"{pad}{indent}{indent}OFFSET " + " ".join(number.format(v) for v in end_sites[j]),
                          f"{pad}{indent}}}"])  # fmt: skip
        lines.append(pad + "}")

    joint(0, 0)
    assert order_written == list(range(len(names))), "joints must be listed depth first"
    frames = len(root_positions)
    columns = [root_positions] + [np.asarray(angles[j]).reshape(frames, -1) for j in range(len(names))]
    data = np.concatenate(columns, axis=1)
    lines += ["MOTION", f"Frames: {frames}", f"Frame Time: {frame_time}"]
    lines += [" ".join(number.format(v) for v in row) for row in data]
    return newline.join(lines) + newline


def reference_positions(parents, offsets, orders, angles, root_positions) -> np.ndarray:
    """(T, J, 3) world joint positions by forward kinematics, one axis matrix per channel."""
    frames = len(root_positions)
    count = len(parents)
    world_r = np.zeros((frames, count, 3, 3))
    world_p = np.zeros((frames, count, 3))
    for j, p in enumerate(parents):
        local = np.broadcast_to(np.eye(3), (frames, 3, 3)).copy()
        for k, axis in enumerate(orders[j]):
            local = local @ axis_matrix(axis, np.asarray(angles[j])[:, k])
        if p < 0:
            world_r[:, j], world_p[:, j] = local, root_positions
        else:
            world_r[:, j] = world_r[:, p] @ local
            world_p[:, j] = world_p[:, p] + world_r[:, p] @ offsets[j]
    return world_p
