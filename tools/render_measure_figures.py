"""Draw docs/measure_landmarks.png (the landmarks, the tapes and the cutting planes of smplcore.measure on the
open model) and docs/open_ages.png (the open model from 1 to 80 years, to scale).

Offscreen with pyrender (``PYOPENGL_PLATFORM=egl``), orthographic cameras so lengths are to scale; labels
with Pillow. Run from the repository root: ``PYOPENGL_PLATFORM=egl python tools/render_measure_figures.py``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import pyrender  # noqa: E402
import trimesh  # noqa: E402
from PIL import Image, ImageDraw, ImageFont  # noqa: E402

import smplcore  # noqa: E402
from smplcore.measure.api import rest_body  # noqa: E402
from smplcore.measure.definitions import measure_body  # noqa: E402
from smplcore.measure.geometry import _basis, pick_loop, section  # noqa: E402

DOCS = Path(__file__).resolve().parents[1] / "docs"
COLORS = {
    "chest": (0.85, 0.2, 0.2),
    "under_bust": (0.95, 0.55, 0.1),
    "waist": (0.2, 0.6, 0.2),
    "hip": (0.2, 0.35, 0.85),
    "thigh": (0.6, 0.25, 0.75),
    "calf": (0.1, 0.65, 0.7),
    "upper_arm": (0.75, 0.6, 0.1),
    "neck": (0.9, 0.3, 0.6),
    "stature": (0.1, 0.1, 0.1),
    "inseam": (0.45, 0.3, 0.15),
    "shoulder_breadth": (0.3, 0.3, 0.3),
    "arm_length": (0.55, 0.55, 0.1),
}


def _tube(points: np.ndarray, radius: float, closed: bool) -> trimesh.Trimesh:
    pts = np.concatenate([points, points[:1]]) if closed else points
    parts = [
        trimesh.creation.cylinder(radius=radius, segment=np.stack([a, b]), sections=8)
        for a, b in zip(pts[:-1], pts[1:])
        if np.linalg.norm(b - a) > 1e-6
    ]
    parts += [trimesh.creation.icosphere(1, radius=radius).apply_translation(p) for p in pts]
    return trimesh.util.concatenate(parts)


def _tape(body, name: str) -> np.ndarray:
    point, normal = body.planes[name]
    loop = pick_loop(section(body.vertices, body.topo, point, normal), point, normal)
    u, w = _basis(normal)
    from scipy.spatial import ConvexHull

    hull = ConvexHull(np.stack([loop.points @ u, loop.points @ w], 1))
    return loop.points[hull.vertices]


def _material(rgb, alpha=1.0):
    return pyrender.MetallicRoughnessMaterial(
        baseColorFactor=(*rgb, alpha),
        metallicFactor=0.0,
        roughnessFactor=0.8,
        alphaMode="BLEND" if alpha < 1 else "OPAQUE",
    )


def _scene(meshes, yaw_deg: float, center: np.ndarray, half_h: float, aspect: float):
    scene = pyrender.Scene(bg_color=(1.0, 1.0, 1.0, 1.0), ambient_light=(0.35, 0.35, 0.35))
    rot = trimesh.transformations.rotation_matrix(np.radians(yaw_deg), [0, 1, 0], point=center)
    for mesh, mat in meshes:
        m = mesh.copy()
        m.apply_transform(rot)
        scene.add(pyrender.Mesh.from_trimesh(m, material=mat, smooth=False))
    cam = pyrender.OrthographicCamera(xmag=half_h * aspect, ymag=half_h, znear=0.01, zfar=10)
    pose = np.eye(4)
    pose[:3, 3] = center + [0, 0, 3.0]
    scene.add(cam, pose=pose)
    for angle, axis in ((-0.5, [1, 0.3, 0]), (0.6, [0.3, 1, 0])):
        scene.add(pyrender.DirectionalLight(intensity=1.6), pose=trimesh.transformations.rotation_matrix(angle, axis))
    return scene


def landmarks_figure(path: Path) -> None:
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    body = rest_body(model)
    values = {k: v.value for k, v in measure_body(body).items()}
    v = body.vertices
    floor = v[:, 1].min()
    body_mesh = trimesh.Trimesh(v, model.faces, process=False)
    meshes = [(body_mesh, _material((0.78, 0.8, 0.84), 0.55))]
    r = 0.004
    for name in ("chest", "under_bust", "waist", "hip", "thigh", "calf", "upper_arm", "neck"):
        meshes.append((_tape(body, name), _material(COLORS[name])))
        meshes[-1] = (_tube(meshes[-1][0], r, True), meshes[-1][1])
    lm = body.landmarks
    top = lm["vertex"]
    x_side = v[:, 0].min() - 0.06
    meshes.append((_tube(np.array([[x_side, floor, 0], [x_side, top[1], 0]]), r, False), _material(COLORS["stature"])))
    crotch = lm["crotch"]
    meshes.append((_tube(np.array([crotch, [crotch[0], floor, crotch[2]]]), r, False), _material(COLORS["inseam"])))
    ra, la = lm["right_acromion"], lm["left_acromion"]
    meshes.append((_tube(np.array([ra, la]) + [0, 0.02, 0], r, False), _material(COLORS["shoulder_breadth"])))
    arm = np.array([ra, body.j("right_elbow"), body.j("right_wrist")]) + [0, 0.0, 0.06]
    meshes.append((_tube(arm, r, False), _material(COLORS["arm_length"])))
    for p in (top, crotch, ra, la, lm["axilla"], lm["sole"]):
        meshes.append((trimesh.creation.icosphere(2, radius=0.012).apply_translation(p), _material((0.1, 0.1, 0.1))))
    W, H = 560, 620
    center = np.array([0.0, 0.5 * (floor + top[1]), 0.0])
    half_h = 0.5 * (top[1] - floor) + 0.08
    renderer = pyrender.OffscreenRenderer(W, H)
    panels = [renderer.render(_scene(meshes, yaw, center, half_h, W / H))[0] for yaw in (0.0, -35.0)]
    renderer.delete()
    img = Image.fromarray(np.concatenate(panels, axis=1))
    legend = Image.new("RGB", (250, H), "white")
    draw = ImageDraw.Draw(legend)
    font = ImageFont.load_default()
    draw.text((10, 10), "open model, mean body", fill="black", font=font)
    units = {"mass": "kg", "bmi": "kg/m2"}
    y = 34
    for name, col in COLORS.items():
        draw.rectangle([10, y + 2, 26, y + 12], fill=tuple(int(c * 255) for c in col))
        draw.text((34, y), f"{name}  {values[name] * 100:.1f} cm", fill="black", font=font)
        y += 20
    for name in ("mass", "bmi"):
        draw.text((34, y), f"{name}  {values[name]:.1f} {units[name]}", fill="black", font=font)
        y += 20
    draw.text((10, y + 10), "dots: vertex, acromia, axilla,", fill="black", font=font)
    draw.text((10, y + 26), "crotch, sole", fill="black", font=font)
    out = Image.new("RGB", (img.width + legend.width, H), "white")
    out.paste(img, (0, 0))
    out.paste(legend, (img.width, 0))
    out = out.resize((out.width * 3 // 4, out.height * 3 // 4), Image.LANCZOS)
    out.save(path, optimize=True)
    print(f"wrote {path} ({path.stat().st_size / 1e3:.0f} KB)")


def ages_figure(path: Path, ages=(1, 3, 6, 10, 14, 18, 40, 80)) -> None:
    meshes, labels, xs = [], [], []
    x = 0.0
    floor_top = 0.0
    for age in ages:
        model = smplcore.BodyModel(model_type="open", age=age, dtype=np.float64)
        v = model(betas=np.zeros((1, 10))).vertices[0].copy()
        v[:, 1] -= v[:, 1].min()
        width = np.ptp(v[:, 0])
        v[:, 0] += x + 0.5 * width - 0.5 * (v[:, 0].max() + v[:, 0].min())
        xs.append(x + 0.5 * width)
        x += width + 0.08
        floor_top = max(floor_top, v[:, 1].max())
        meshes.append((trimesh.Trimesh(v, model.faces, process=False), _material((0.65, 0.74, 0.86))))
        labels.append(f"{age} y, {np.ptp(v[:, 1]) * 100:.0f} cm")
    total = x - 0.08
    W, H = 1400, 360
    half_h = 0.5 * floor_top + 0.12
    aspect = W / H
    half_w = max(half_h * aspect, 0.5 * total + 0.05)
    half_h = half_w / aspect
    center = np.array([0.5 * total, 0.5 * floor_top + 0.05, 0.0])
    renderer = pyrender.OffscreenRenderer(W, H)
    color = renderer.render(_scene(meshes, 0.0, center, half_h, aspect))[0]
    renderer.delete()
    img = Image.fromarray(color)
    draw = ImageDraw.Draw(img)
    font = ImageFont.load_default()
    for cx, text in zip(xs, labels):
        px = (cx - center[0]) / half_w * W / 2 + W / 2
        draw.text((px - 3 * len(text), H - 22), text, fill="black", font=font)
    img.save(path, optimize=True)
    print(f"wrote {path} ({path.stat().st_size / 1e3:.0f} KB)")


if __name__ == "__main__":
    landmarks_figure(DOCS / "measure_landmarks.png")
    ages_figure(DOCS / "open_ages.png")
