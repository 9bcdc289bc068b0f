"""Draw every keypoint convention on the open model: docs/keypoints/<convention>.png.

The open model in its rest (T) pose is rendered offscreen (pyrender, ``PYOPENGL_PLATFORM=egl``)
from the front; each convention's points that the open model provides are projected with the
renderer's own camera and labelled with their index (PIL). Blue: exact, green: synthesised (a
documented midpoint), orange: approximate; points the open model lacks are listed as missing.

Points come from smplcore's own open-model regressors for coco17 / h36m17 / openpose25, and for
the other conventions from :func:`smplcore.keypoints.convert` out of the open model's 45 output
joints plus those regressors' points.

Run from the repository root: ``PYOPENGL_PLATFORM=egl python tools/render_keypoint_figures.py``.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

import smplcore
from smplcore import keypoints as kp
from smplcore.render import offscreen

OUT = Path(__file__).resolve().parents[1] / "docs" / "keypoints"
FIGURES = (
    "coco17",
    "openpose18",
    "openpose25",
    "openpose135",
    "openpose137",
    "coco_wholebody133",
    "mediapipe33",
    "mpii16",
    "h36m17",
    "smpl24",
    "smpl45",
    "smplh73",
    "smplx127",
    "smplx144",
    "mano21",
)
_COLOURS = {"exact": (30, 70, 200), "synthesised": (20, 150, 60), "approximate": (235, 120, 10)}
_OWN = ("coco17", "h36m17", "openpose25")


def _project(points: np.ndarray, verts: np.ndarray, width: int, height: int, yfov_deg: float) -> np.ndarray:
    """Pixel (u, v) of 3-D points in the front view ``offscreen.render_mesh`` draws of ``verts``."""
    placed, moved = offscreen._layout(verts[None], points[None], 0.0)
    lo, hi = placed.reshape(-1, 3).min(axis=0), placed.reshape(-1, 3).max(axis=0)
    pose, _, _, _ = offscreen._frame(lo, hi, math.radians(yfov_deg), width / height)
    eye = pose[:3, 3]
    p = moved[0] - eye  # the camera looks down -Z without rotation in the front view
    t = math.tan(math.radians(yfov_deg) / 2)
    x = p[:, 0] / (-p[:, 2] * t * width / height)
    y = p[:, 1] / (-p[:, 2] * t)
    return np.stack([(x + 1) / 2 * width, (1 - y) / 2 * height], axis=1)


def _sources(model: smplcore.BodyModel, out) -> tuple[np.ndarray, list[str]]:
    verts = out.vertices[0]
    points, names = [out.joints[0]], list(model.joint_names)
    for convention in _OWN:
        reg = kp.open_model_regressor(convention)
        points.append(reg.apply(verts))
        names += list(reg.qualified_names())
    return np.concatenate(points), names


def draw(convention: str, base: np.ndarray, verts: np.ndarray, src_points: np.ndarray, src_names: list[str], args):
    if convention in _OWN:
        points = kp.open_model_regressor(convention).apply(verts)
        how = ("exact",) * len(points)
    else:
        dst = convention
        if convention.startswith("mano"):  # MANO's side-less names, drawn on the open model's left hand
            dst = ["left_wrist" if n == "wrist" else n.replace("hand_", "left_") for n in kp.names(convention)]
        plan = kp.plan(src_names, dst)
        points = kp.convert(src_points, src_names, dst)[0]
        how = plan.how
    uv = _project(points, verts, args.size, args.size, 30)
    image = Image.fromarray(base).convert("RGB")
    ink = ImageDraw.Draw(image)
    font = ImageFont.truetype("DejaVuSans.ttf", args.font) if args.font else ImageFont.load_default()
    title = ImageFont.truetype("DejaVuSans-Bold.ttf", 16)
    names = kp.names(convention)
    drawn = [i for i, h in enumerate(how) if h != "missing"]
    for i in drawn:
        u, v = uv[i]
        colour = _COLOURS[how[i]]
        ink.ellipse([u - 3, v - 3, u + 3, v + 3], fill=colour, outline=(255, 255, 255))
        label = str(i)
        dx = 5 if u >= args.size / 2 else -5 - ink.textlength(label, font=font)
        ink.text((u + dx, v - args.font / 2 - 1), label, fill=colour, font=font)
    counts = {h: how.count(h) for h in ("exact", "synthesised", "approximate", "missing")}
    ink.text((10, 8), f"{convention}: {len(names)} points", fill=(0, 0, 0), font=title)
    x = 10
    for h, n in counts.items():
        if n:
            text = f"{n} {h}"
            ink.text((x, 30), text, fill=_COLOURS.get(h, (120, 120, 120)), font=font)
            x += ink.textlength(text, font=font) + 14
    missing = [names[i] for i, h in enumerate(how) if h == "missing"]
    if missing:
        if len(missing) <= 16:
            text = "missing on the open model: " + ", ".join(missing)
        else:
            text = f"{len(missing)} missing: face landmarks and finger joints, which the open model does not have"
        lines, line = [], ""
        for word in text.split(" "):
            if ink.textlength(line + " " + word, font=font) > args.size - 20:
                lines.append(line)
                line = word
            else:
                line = f"{line} {word}".strip()
        lines.append(line)
        for k, line in enumerate(lines):
            ink.text((10, args.size - 8 - 14 * (len(lines) - k)), line, fill=(120, 120, 120), font=font)
    path = args.out / f"{convention}.png"
    _save_small(image, path)
    return path, counts


def _save_small(image: Image.Image, path: Path) -> None:
    """A palette PNG whose palette holds the label colours exactly and 56 shades of the render."""
    shades = image.convert("RGB").quantize(colors=56, method=Image.Quantize.MEDIANCUT).getpalette()[: 3 * 56]
    fixed = [c for rgb in (*_COLOURS.values(), (0, 0, 0), (60, 60, 60), (120, 120, 120), (255, 255, 255)) for c in rgb]
    palette = Image.new("P", (1, 1))
    palette.putpalette(fixed + shades + [0] * (768 - len(fixed) - len(shades)))
    image.quantize(palette=palette, dither=Image.Dither.NONE).save(path, optimize=True)


def tables() -> str:
    """The conventions table and the approximate-pair table of docs/keypoints.md, as Markdown."""
    from smplcore.keypoints.approximate import definition

    ref = kp.names("smplx144")
    lines = ["| convention | points | names shared with smplx144 | of them the same point | approximate pairs |"]
    lines.append("| --- | ---: | ---: | ---: | --- |")
    for key in kp.conventions():
        names = kp.names(key)
        shared = [n for n in names if n in ref]
        same = [n for n in shared if definition(key, n) == definition("smplx144", n)]
        pairs = [r for r in kp.APPROXIMATE if key in r.conventions]
        text = ", ".join(f"`{r.name}`~`{r.like}`" if r.name != r.like else f"`{r.name}`" for r in pairs) or "-"
        lines.append(f"| `{key}` | {len(names)} | {len(shared)} | {len(same)} | {text} |")
    lines += ["", "| conventions | points (~ the smplx point they approximate) | what differs |", "| --- | --- | --- |"]
    groups: dict[tuple, list[str]] = {}
    for r in kp.APPROXIMATE:
        groups.setdefault((r.conventions, r.note), []).append(r.name if r.name == r.like else f"{r.name}~{r.like}")
    for (conventions, note), points in groups.items():
        listed = ", ".join(f"`{c}`" for c in conventions)
        lines.append(f"| {listed} | {', '.join(f'`{p}`' for p in points)} | {note} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--size", type=int, default=720)
    parser.add_argument("--font", type=int, default=11)
    parser.add_argument("--tables", action="store_true", help="print the Markdown tables of docs/keypoints.md")
    parser.add_argument("conventions", nargs="*", default=list(FIGURES))
    args = parser.parse_args(argv)
    if args.tables:
        print(tables())
        return
    args.out.mkdir(parents=True, exist_ok=True)
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    out = model()
    verts = out.vertices[0]
    base = offscreen.render_mesh(verts, model.faces, width=args.size, height=args.size, color=(0.82, 0.84, 0.88))
    src_points, src_names = _sources(model, out)
    for convention in args.conventions:
        path, counts = draw(convention, base, verts, src_points, src_names, args)
        print(f"{path} ({path.stat().st_size // 1024} KB): {counts}")


if __name__ == "__main__":
    main()
