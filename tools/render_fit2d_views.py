"""docs/fit_real_2d.png: 2D fits of held-out real motion capture seen through the camera and from the side.

    python tools/render_fit2d_views.py [--out docs/fit_real_2d.png] [--rows 4 17 33]

Bodies and views of ``bench/fit2d_real.py`` (CMU subject 06 through random cameras, 2-5 px noise, drops,
images cut at the hips or knees; needs the shared mocap). Per row: the image with the keypoints and the fit
drawn through its camera (``smplcore.render.render_overlay``), then from the side (``side_view``: the
camera turned 90° about the vertical) the truth (green) with the fit without this wave's upright prior and
image-edge rule (orange), and with them (blue).
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))

import fit2d_real  # noqa: E402

import smplcore  # noqa: E402
from smplcore import fit  # noqa: E402
from smplcore.render import render_overlay, save_png, side_view  # noqa: E402

TRUTH, BEFORE, AFTER = (0.55, 0.8, 0.5), (0.95, 0.6, 0.3), (0.5, 0.7, 0.95)
CELL = 360


def _fit(model, view, new_rules: bool):
    camera = fit.Camera(focal=view["f"], center=view["centre"], **({"image_size": view["size"]} if new_rules else {}))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = fit.fit_keypoints(model, view["keypoints"][None], camera=camera, **({} if new_rules else {"upright": 0.0}))
    return np.asarray(model(**r.params).vertices)[0]


def _fit_in(image: np.ndarray, size: int = CELL) -> np.ndarray:
    """``image`` scaled to fit a white size x size cell."""
    from PIL import Image

    h, w = image.shape[:2]
    scale = size / max(h, w)
    small = np.asarray(Image.fromarray(image).resize((max(1, round(w * scale)), max(1, round(h * scale)))))
    cell = np.full((size, size, 3), 255, np.uint8)
    y, x = (size - small.shape[0]) // 2, (size - small.shape[1]) // 2
    cell[y : y + small.shape[0], x : x + small.shape[1]] = small
    return cell


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "fit_real_2d.png"))
    parser.add_argument("--images", type=int, default=60)
    parser.add_argument("--rows", nargs="+", default=["full:4", "hips:17", "knees:33"])
    args = parser.parse_args()
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    bodies = fit2d_real.truth(model, 30)
    pick = np.linspace(0, len(bodies["transl"]) - 1, args.images).astype(int)
    bodies = {k: v[pick] for k, v in bodies.items()}
    grid = []
    for spec in args.rows:
        kind, index = spec.split(":")
        view = fit2d_real.views(model, bodies, kind, "coco17", np.random.default_rng(0))[int(index)]
        before, after = _fit(model, view, False), _fit(model, view, True)
        truth = {k: v[[int(index)]] for k, v in bodies.items()}
        camera = fit.Camera(focal=view["f"], center=view["centre"], image_size=view["size"])
        # the truth in the fit's world (camera space): the views store it there
        joints_world = np.asarray(model(**truth).joints)[0]
        rot, t = _rigid(joints_world, view["joints"])
        true_vertices = np.asarray(model(**truth).vertices)[0] @ rot.T + t
        overlay = render_overlay(None, after, model.faces, camera, keypoints=view["keypoints"], color=AFTER)
        identity = fit.Camera(focal=1.0, center=(0.0, 0.0))
        both = [
            side_view(np.stack([true_vertices, v]), model.faces, identity, color=[TRUTH, c], width=CELL, height=CELL)
            for v, c in ((before, BEFORE), (after, AFTER))
        ]
        grid.append(np.concatenate([_fit_in(overlay), *both], axis=1))
    save_png(np.concatenate(grid, axis=0), args.out)
    print(args.out)


def _rigid(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """R, t with b ≈ R a + t (the view's camera: the truth's joints in world and camera space)."""
    ca, cb = a.mean(0), b.mean(0)
    u, _, vt = np.linalg.svd((b - cb).T @ (a - ca))
    rot = u @ np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))]) @ vt
    return rot, cb - rot @ ca


if __name__ == "__main__":
    main()
