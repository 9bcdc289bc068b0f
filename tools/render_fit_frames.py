"""Draw docs/fit_frames.png: the frames of a 2D fit, through the command line's round trip.

A person (the open model) seen by a camera (f = 1000 px, 1280 x 720) is written as OpenPose frames; ``smplcore
fit`` fits them and ``smplcore export`` writes the result as a .glb. Three panels: (1) the keypoints in the image
(OpenCV pixels: y down); (2) the exported .glb's first frame, posed from its root and joint rotations (as a glTF
viewer does), seen from the front as ``smplcore render`` sees it: upright, facing the camera; (3) the world of
the output: Y up, the feet on the ground y = 0 (grey grid), the first frame's pelvis above the origin (axes: X
red, Y green, Z blue), and the camera where the output's ``camera_extrinsics`` put it, looking at the body.

Run from the repository root: ``PYOPENGL_PLATFORM=egl python tools/render_fit_frames.py``.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # the synthetic scenes of the tests

import smplcore  # noqa: E402
from smplcore import fit  # noqa: E402
from smplcore.cli import main  # noqa: E402
from smplcore.motion import load_motion  # noqa: E402
from smplcore.render import render_mesh  # noqa: E402

OUT = ROOT / "docs" / "fit_frames.png"
W, H = 1280, 720
PANEL = 360
BONES = [("nose", "neck"), ("neck", "mid_hip")] + [
    pair
    for side in ("left", "right")
    for pair in (
        ("neck", f"{side}_shoulder"), (f"{side}_shoulder", f"{side}_elbow"), (f"{side}_elbow", f"{side}_wrist"),
        ("mid_hip", f"{side}_hip"), (f"{side}_hip", f"{side}_knee"), (f"{side}_knee", f"{side}_ankle"),
        (f"{side}_ankle", f"{side}_heel"), (f"{side}_ankle", f"{side}_big_toe"),
    )
]  # fmt: skip


def make_fit(folder: Path) -> tuple[np.ndarray, Path, Path]:
    from fakes_fit2d import natural_poses, scene, write_openpose

    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    camera = fit.Camera(focal=1000.0, center=(W / 2, H / 2))
    rng = np.random.default_rng(11)
    seq = {k: np.repeat(v, 3, 0) for k, v in natural_poses(model, 1, rng).items()}
    seq["transl"][:, :2] = [0.1, 0.2]
    frames, _, _ = scene(model, seq, rng, convention="openpose25", camera=camera)
    write_openpose(folder / "openpose", frames)
    out, glb = folder / "fit.npz", folder / "fit.glb"
    assert (
        main(["fit", str(folder / "openpose"), "-o", str(out), "--focal", "1000", "--center", f"{W / 2},{H / 2}"]) == 0
    )
    assert main(["export", str(out), "-o", str(glb)]) == 0
    return frames[0], out, glb


def keypoint_panel(points: np.ndarray) -> Image.Image:
    from smplcore import keypoints as kp

    scale = PANEL / H
    image = Image.new("RGB", (int(W * scale), PANEL), "white")
    draw = ImageDraw.Draw(image)
    index = {n: i for i, n in enumerate(kp.layout("openpose25").names)}
    for a, b in BONES:
        draw.line(
            [tuple(points[index[a], :2] * scale), tuple(points[index[b], :2] * scale)], fill=(90, 90, 90), width=2
        )
    for x, y, c in points:
        if c > 0:
            draw.ellipse([x * scale - 3, y * scale - 3, x * scale + 3, y * scale + 3], fill=(20, 160, 60))
    draw.rectangle([0, 0, image.width - 1, image.height - 1], outline=(180, 180, 180))
    return image


def glb_vertices(glb: Path) -> tuple[np.ndarray, np.ndarray]:
    """The .glb's first frame posed by a reader of its own (tests/export_helpers.GlbReader): world vertices."""
    from export_helpers import GlbReader

    reader = GlbReader(glb)
    world = reader.world_matrices(0)
    gltf = reader.gltf
    prim = gltf.meshes[0].primitives[0]
    verts = reader.array(prim.attributes.POSITION)
    joints = reader.array(prim.attributes.JOINTS_0)
    weights = reader.array(prim.attributes.WEIGHTS_0)
    skin = gltf.skins[0]
    ibm = reader.array(skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)
    mats = world[skin.joints] @ ibm
    blended = np.einsum("vk,vkij->vij", weights, mats[joints])
    posed = np.einsum("vij,vj->vi", blended, np.c_[verts, np.ones(len(verts))])[:, :3]
    faces = reader.array(prim.indices).reshape(-1, 3)
    return posed, faces


def world_panel(out: Path) -> Image.Image:
    import pyrender
    import trimesh

    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    motion = load_motion(out)
    verts = np.asarray(model(**motion.model_params("open")).vertices[0])
    with np.load(out) as data:
        extrinsics = data["camera_extrinsics"][0]
    rot, trans = extrinsics[:3, :3], extrinsics[:3, 3]
    eye = -rot.T @ trans
    scene = pyrender.Scene(bg_color=[1.0, 1.0, 1.0, 1.0], ambient_light=[0.35, 0.35, 0.35])
    body = trimesh.Trimesh(verts, model.faces, process=False)
    material = pyrender.MetallicRoughnessMaterial(baseColorFactor=[0.55, 0.65, 0.85, 1.0], roughnessFactor=0.8)
    scene.add(pyrender.Mesh.from_trimesh(body, material=material, smooth=True))

    def add(mesh: trimesh.Trimesh, color) -> None:
        mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=[*color, 1.0], roughnessFactor=1.0)
        scene.add(pyrender.Mesh.from_trimesh(mesh, material=mat, smooth=False))

    extent = max(3.0, float(np.hypot(eye[0], eye[2])) + 1.0)
    for k in np.arange(-extent, extent + 1e-9, 0.5):  # the ground grid, y = 0
        add(trimesh.creation.box([2 * extent, 0.004, 0.01], trimesh.transformations.translation_matrix([0, 0, k])),
            (0.75, 0.75, 0.75))  # fmt: skip
        add(trimesh.creation.box([0.01, 0.004, 2 * extent], trimesh.transformations.translation_matrix([k, 0, 0])),
            (0.75, 0.75, 0.75))  # fmt: skip
    for axis, color in ((0, (0.85, 0.1, 0.1)), (1, (0.1, 0.7, 0.1)), (2, (0.1, 0.2, 0.9))):
        size = [0.03, 0.03, 0.03]
        size[axis] = 0.6
        centre = [0.0, 0.0, 0.0]
        centre[axis] = 0.3
        add(trimesh.creation.box(size, trimesh.transformations.translation_matrix(centre)), color)
    # the camera: a pyramid from its centre along its viewing direction (OpenCV +z)
    depth, half_w, half_h = 0.5, 0.5 * (W / 2) / 1000.0, 0.5 * (H / 2) / 1000.0
    corners = [np.array([sx * half_w, sy * half_h, depth]) for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    world = [rot.T @ c + eye for c in corners]
    for a, b in [(eye, w) for w in world] + [(world[i], world[(i + 1) % 4]) for i in range(4)]:
        seg = trimesh.creation.cylinder(radius=0.015, segment=[a, b])
        add(seg, (0.2, 0.2, 0.2))
    add(trimesh.creation.icosphere(radius=0.06).apply_translation(eye), (0.2, 0.2, 0.2))

    target = np.array([0.0, 0.8, eye[2] / 2])
    view = target + np.array([4.5, 3.0, 2.5]) * max(1.0, eye[2] / 5.0)
    forward = (target - view) / np.linalg.norm(target - view)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([right, up, -forward], axis=1)
    pose[:3, 3] = view
    scene.add(pyrender.PerspectiveCamera(yfov=np.radians(40.0), aspectRatio=1.3), pose=pose)
    scene.add(pyrender.DirectionalLight(color=np.ones(3), intensity=3.0), pose=pose)
    renderer = pyrender.OffscreenRenderer(int(PANEL * 1.3), PANEL)
    try:
        color, _ = renderer.render(scene)
    finally:
        renderer.delete()
    return Image.fromarray(color)


def label(image: Image.Image, text: str) -> Image.Image:
    out = Image.new("RGB", (image.width, image.height + 28), "white")
    out.paste(image, (0, 28))
    try:
        font = ImageFont.truetype("DejaVuSans.ttf", 15)
    except OSError:
        font = ImageFont.load_default()
    ImageDraw.Draw(out).text((6, 5), text, fill=(0, 0, 0), font=font)
    return out


def main_figure() -> Path:
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    with tempfile.TemporaryDirectory() as tmp:
        points, out, glb = make_fit(Path(tmp))
        verts, faces = glb_vertices(glb)
        front = Image.fromarray(render_mesh(verts, faces, width=PANEL * 3 // 4, height=PANEL, camera="front"))
        panels = [
            label(keypoint_panel(points), "1. OpenPose keypoints (pixels, y down)"),
            label(front, "2. fit.glb, front view"),
            label(world_panel(out), "3. the output's world: Y up, ground y = 0, the camera"),
        ]
    width = sum(p.width for p in panels) + 10 * (len(panels) - 1)
    figure = Image.new("RGB", (width, max(p.height for p in panels)), "white")
    x = 0
    for panel in panels:
        figure.paste(panel, (x, 0))
        x += panel.width + 10
    figure = figure.convert("P", palette=Image.Palette.ADAPTIVE, colors=128)
    figure.save(OUT, optimize=True)
    return OUT


if __name__ == "__main__":
    path = main_figure()
    print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KB)")
