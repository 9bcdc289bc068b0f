"""Look at the pose prior's training data: front and side renders of retargeted mocap frames.

For each clip given (paths under the shared mocap folder), the clip is retargeted as
tools/train_pose_prior.py does (calibrated on the given clips of the same performer only) and three frames
(start, a third, two thirds) are drawn: the open model's mesh, half transparent, with the re-posed skeleton's
targets as red spheres; the body's heading is undone so "side" is seen from the body's left. Writes
``build/pose_prior/<clip>.png``::

    PYOPENGL_PLATFORM=egl python tools/render_pose_prior_frames.py cmu_mb_jonathanalderson/05_01.bvh.gz
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
sys.path.insert(0, str(ROOT / "src"))

from pose_prior_retarget import calibration, clip_motion, model_rest, retarget  # noqa: E402
from train_pose_prior import subject_of  # noqa: E402

import smplcore  # noqa: E402
from smplcore.engine import rodrigues  # noqa: E402
from smplcore.render import render_mesh  # noqa: E402


def panel(model, params: dict, targets: np.ndarray, frames: list[int], title: str) -> Image.Image:
    """Front and side renders (300 x 360 each) of the given frames, one row per frame."""
    out = model(**params)
    joints, verts = np.asarray(out.joints), np.asarray(out.vertices)
    rows = []
    for t in frames:
        forward = rodrigues(np.asarray(params["global_orient"], np.float64)[t : t + 1])[0][:, 2]
        yaw = np.arctan2(forward[0], forward[2])
        c, s = np.cos(yaw), np.sin(yaw)
        unturn = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])
        centre = joints[t, 0]
        v, p = (verts[t] - centre) @ unturn.T, (targets[t] - centre) @ unturn.T
        views = [
            render_mesh(v, model.rig.faces, width=300, height=360, camera=cam, joints=p, alpha=0.6, joint_radius=0.02)
            for cam in ("front", "side")
        ]
        rows.append(np.concatenate(views, axis=1))
    img = Image.fromarray(np.concatenate(rows, axis=0))
    draw = ImageDraw.Draw(img)
    for i, t in enumerate(frames):
        draw.text((5, 5 + 360 * i), f"{title} frame {t} (30 fps): front | side", fill="black")
    return img


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("clips", nargs="+", help="paths under --mocap, e.g. cmu_mb_jonathanalderson/05_01.bvh.gz")
    ap.add_argument("--mocap", type=Path, default=ROOT.parent / "shared" / "data" / "mocap")
    ap.add_argument("--out", type=Path, default=ROOT / "build" / "pose_prior")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    model = smplcore.BodyModel(model_type="open")
    rest = model_rest(model)
    motions = {c: clip_motion(args.mocap / c, 30.0, not c.startswith(("fair", "cmu_max"))) for c in args.clips}
    for clip, motion in motions.items():
        same = [m for c, m in motions.items() if subject_of(c) == subject_of(clip)]
        fit, targets = retarget(model, rest, motion, calibration(same))
        n = len(fit.frames)
        params = {"body_pose": fit.body_pose, "global_orient": fit.global_orient, "transl": fit.transl}
        path = args.out / (Path(clip).name.split(".")[0] + ".png")
        panel(model, params, targets, [0, n // 3, 2 * n // 3], Path(clip).name).save(path)
        print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
