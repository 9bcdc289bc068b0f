"""Draw docs/dqs_twist.png: the open model's left forearm with the wrist twisted by 150° about the forearm
axis, linear blend skinning (left) against dual-quaternion skinning (right), and measure the forearm.

The arm (the vertices that the elbow, the wrist and the hand weight most) is cut out of the posed mesh,
turned so that the forearm points up, drawn with the UV-grid texture (the grid's lines show the twist)
by smplcore's offscreen renderer (pyrender, ``PYOPENGL_PLATFORM=egl``), and labelled with the radius
that each keeps near the wrist (mean distance from the elbow-wrist axis of the vertices at 85-95 % of
the forearm's length, posed over rest) and in the blend zone (wrist weight 0.3-0.7).

Run from the repository root: ``PYOPENGL_PLATFORM=egl python tools/render_dqs_twist.py``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

import smplcore
from smplcore.render import offscreen

OUT = Path(__file__).resolve().parents[1] / "docs" / "dqs_twist.png"


def twisted_arm(skinning: str, degrees: float) -> dict:
    """The posed and rest mesh, the rest joints, the forearm's joints and axis, for ``skinning``."""
    model = smplcore.BodyModel(model_type="open", dtype=np.float64, skinning=skinning)
    names = model.skeleton_joint_names
    elbow, wrist = names.index("left_elbow"), names.index("left_wrist")
    rest, joints = model.rest_pose()
    axis = (joints[wrist] - joints[elbow]) / np.linalg.norm(joints[wrist] - joints[elbow])
    pose = np.zeros((1, 3 * (len(names) - 1)))
    pose[0, 3 * (wrist - 1) : 3 * wrist] = np.radians(degrees) * axis
    return {
        "model": model,
        "posed": model(body_pose=pose).vertices[0],
        "rest": rest,
        "joints": joints,
        "elbow": elbow,
        "wrist": wrist,
        "hand": names.index("left_hand"),
        "axis": axis,
    }


def radius_ratios(arm: dict) -> dict[str, float]:
    """Posed over rest mean distance from the elbow-wrist axis: near the wrist and in the blend zone."""
    base, axis, rest = arm["joints"][arm["elbow"]], arm["axis"], arm["rest"]
    length = np.linalg.norm(arm["joints"][arm["wrist"]] - base)

    def radius(v: np.ndarray) -> np.ndarray:
        d = v - base
        return np.linalg.norm(d - (d @ axis)[:, None] * axis, axis=1)

    along = (rest - base) @ axis / length
    w, e, wr = arm["model"].skinning_weights, arm["elbow"], arm["wrist"]
    rings = {
        "forearm": (along > 0.85) & (along < 0.95) & (radius(rest) < 0.1),
        "blend": (w[:, wr] >= 0.3) & (w[:, wr] <= 0.7) & (w[:, e] + w[:, wr] > 0.95),
    }
    return {k: float(radius(arm["posed"])[m].mean() / radius(rest)[m].mean()) for k, m in rings.items()}


def arm_submesh(arm: dict) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """Faces of the forearm and hand (every corner weighted most by the elbow, the wrist or the hand), the
    vertices turned so that the forearm points up, and the UV map of those faces."""
    model = arm["model"]
    dominant = model.skinning_weights.argmax(axis=1)
    keep = np.isin(dominant, [arm["elbow"], arm["wrist"], arm["hand"]])
    faces = np.asarray(model.faces)
    face_mask = keep[faces].all(axis=1)
    vt, ft = model.uv
    # a rotation taking the forearm axis to +Y (Rodrigues about axis × Y)
    a, y = arm["axis"], np.array([0.0, 1.0, 0.0])
    k = np.cross(a, y)
    s, c = np.linalg.norm(k), float(a @ y)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]]) / max(s, 1e-12)
    rot = np.eye(3) + s * kx + (1 - c) * kx @ kx
    used, local = np.unique(faces[face_mask], return_inverse=True)  # the arm's vertices, renumbered
    verts = (arm["posed"][used] - arm["joints"][arm["elbow"]]) @ rot.T
    return verts, local.reshape(-1, 3), (vt, ft[face_mask])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--degrees", type=float, default=150.0)
    ap.add_argument("--output", type=Path, default=OUT)
    ap.add_argument("--size", type=int, default=520, help="height of the picture in pixels")
    args = ap.parse_args(argv)
    arms = {s: twisted_arm(s, args.degrees) for s in ("lbs", "dqs")}
    ratios = {s: radius_ratios(a) for s, a in arms.items()}
    for s, r in ratios.items():
        print(f"{s}: forearm radius near the wrist {100 * r['forearm']:.1f} %, blend zone {100 * r['blend']:.1f} %")
    meshes = [arm_submesh(arms[s]) for s in ("lbs", "dqs")]
    faces, uv = meshes[0][1], meshes[0][2]
    image = offscreen.render_mesh(
        np.stack([m[0] for m in meshes]),
        faces,
        width=int(args.size * 1.1),
        height=args.size,
        camera="front",
        uv=uv,
        texture="uv-grid",
    )
    header = args.size // 7
    picture = Image.new("RGB", (image.shape[1], image.shape[0] + header), (255, 255, 255))
    picture.paste(Image.fromarray(image), (0, header))
    draw = ImageDraw.Draw(picture)
    try:
        font = ImageFont.truetype("DejaVuSans.ttf", max(12, args.size // 32))
    except OSError:
        font = ImageFont.load_default()
    width = picture.width
    for i, s in enumerate(("lbs", "dqs")):
        r = ratios[s]
        text = (
            f"{s.upper()}\nradius {100 * r['forearm']:.0f} % near the wrist\n{100 * r['blend']:.0f} % in the blend zone"
        )
        x = width * (0.25 + 0.5 * i)
        draw.multiline_text((x, 10), text, fill=(20, 20, 20), font=font, anchor="ma", align="center")
    draw.text(
        (width / 2, picture.height - 10),
        f"open model, left wrist turned {args.degrees:.0f}° about the forearm",
        fill=(80, 80, 80),
        font=font,
        anchor="md",
    )
    args.output.parent.mkdir(parents=True, exist_ok=True)
    picture.save(args.output, optimize=True)
    print(f"wrote {args.output} ({args.output.stat().st_size / 1e3:.0f} kB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
