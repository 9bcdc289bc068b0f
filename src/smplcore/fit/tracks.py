"""People followed over the frames of a keypoint sequence (OpenPose lists the people of each frame in no
stable order): simple tracking by the overlap of their keypoints' boxes.

Each frame's people (those with ``min_points`` keypoints of confidence ``min_confidence`` or more) are
matched to the tracks seen in the last ``max_gap`` frames by the intersection over union of their
bounding boxes (the Hungarian assignment on ``1 − IoU``), a pair counting when the IoU is at least
``min_iou`` or, for boxes that do not overlap (a fast move, a gap), when their centres are within half the
track's box diagonal; a person left unmatched starts a new track. Tracks are numbered by the frames they
cover, the longest first (ties: the earlier first), so track 0 is the person seen most.
"""

from __future__ import annotations

import numpy as np

from smplcore.errors import ShapeError


def _box(points: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """(4,) x0, y0, x1, y1 of the seen (K, 2) points."""
    xy = points[seen]
    return np.concatenate([xy.min(0), xy.max(0)])


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    w = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    h = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = w * h
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


def _near(track: np.ndarray, box: np.ndarray) -> bool:
    centre = 0.5 * (track[:2] + track[2:]) - 0.5 * (box[:2] + box[2:])
    return bool(np.hypot(*centre) <= 0.5 * np.hypot(*(track[2:] - track[:2])))


def track_people(
    points: np.ndarray, *, min_confidence: float = 0.1, min_points: int = 6, min_iou: float = 0.1, max_gap: int = 10
) -> np.ndarray:
    """(T, P, K, 3) keypoints (x, y, confidence per frame, person and point) → (T, N, K, 3): the N tracks'
    keypoints, zeros in the frames where a track is not seen (see the module docstring)."""
    from scipy.optimize import linear_sum_assignment

    pts = np.asarray(points, np.float64)
    if pts.ndim != 4 or pts.shape[-1] != 3:
        raise ShapeError(f"points: expected (T, P, K, 3) x, y, confidence, got {pts.shape}")
    frames, people = pts.shape[:2]
    seen = pts[..., 2] >= min_confidence
    boxes: list[np.ndarray] = []  # each track's last box
    last: list[int] = []  # the frame each track was last seen in
    rows: list[dict[int, int]] = []  # per track: frame -> person index
    for t in range(frames):
        present = [p for p in range(people) if seen[t, p].sum() >= min_points]
        live = [i for i in range(len(boxes)) if t - last[i] <= max_gap]
        found = {p: _box(pts[t, p, :, :2], seen[t, p]) for p in present}
        pairs: list[tuple[int, int]] = []
        if live and present:
            iou = np.array([[_iou(boxes[i], found[p]) for p in present] for i in live])
            for r, c in zip(*linear_sum_assignment(1.0 - iou), strict=True):
                if iou[r, c] >= min_iou or (iou[r, c] == 0 and _near(boxes[live[r]], found[present[c]])):
                    pairs.append((live[r], present[c]))
        matched = {p for _, p in pairs}
        for i, p in pairs:
            boxes[i], last[i] = found[p], t
            rows[i][t] = p
        for p in present:
            if p not in matched:
                boxes.append(found[p])
                last.append(t)
                rows.append({t: p})
    order = sorted(range(len(rows)), key=lambda i: (-len(rows[i]), min(rows[i])))
    out = np.zeros((frames, len(order), pts.shape[2], 3))
    for n, i in enumerate(order):
        for t, p in rows[i].items():
            out[t, n] = pts[t, p]
    return out
