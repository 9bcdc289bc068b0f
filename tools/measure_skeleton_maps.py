"""Measure the skeleton maps of smplcore.skeletons on real clips: fit_joints error and spine / neck angles.

For each clip (one per skeleton family, from the shared mocap): the clip is read, turned into targets by
``to_model_targets`` with the map (and with the variants listed below, to compare the choices), 120 frames
spread over the clip are fitted with ``fit_joints(share_betas=True)`` on the open model, and the table gives
the mean joint error (mm), the median summed spine flexion (spine1 + spine2 + spine3, x component, degrees;
positive = forward), the median rotation angle of spine3 and of the neck, the median neck + head flexion, and
the share of frames whose pose leaves :data:`smplcore.fit.priors.JOINT_LIMITS` at the spine (any of spine1-3),
the neck / head, the elbows and the knees. ``--render`` writes a side view of one fitted frame per clip.

    python tools/measure_skeleton_maps.py [--mocap ../shared/data/mocap] [--frames 120] [--render out.png] [--chosen]

(``PYOPENGL_PLATFORM=egl`` for ``--render`` without a display; docs/skeletons_side.png is ``--chosen --render``.)
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

import smplcore  # noqa: E402
from smplcore import fit, skeletons  # noqa: E402
from smplcore.fit.priors import joint_limits  # noqa: E402
from smplcore.skeletons.mapping import Target  # noqa: E402

CLIPS = {
    "cmu_daz": ["cmu_daz_ateliercircle/02_01.bvh.gz", "cmu_daz_aclstm/135_03.bvh.gz"],
    "cmu_mb": ["cmu_mb_jonathanalderson/06_01.bvh.gz", "cmu_mb_jonathanalderson/05_10.bvh.gz"],
    "cmu_max": ["cmu_max_bvh11/131_02.bvh.gz"],
    "fair": ["fair_animateddrawings/jumping.bvh.gz", "fair_animateddrawings/zombie.bvh.gz"],
}


#: The joint at the top of each skeleton's spine: its rotation relative to the root is the mocap's own spine bend.
CHEST = {"cmu_daz": "chest", "cmu_mb": "Spine1", "cmu_max": "Chest2", "fair": "Spine3"}


def own_spine_flex(clip, name: str, frames: np.ndarray) -> float:
    """Median forward flexion (degrees) of the chest relative to the root in the clip itself (both frames are the
    world axes in the rest pose, so the relative rotation's x component is the bend; Z-up files turned first)."""
    from scipy.spatial.transform import Rotation

    rot, _ = clip.world_transforms()
    rot = rot[frames]
    relative = np.swapaxes(rot[:, 0], -1, -2) @ rot[:, clip.joint_names.index(CHEST[name])]
    axes = skeletons.units.AXES[skeletons.skeleton_map(name).up]
    flex = Rotation.from_matrix(axes @ relative @ axes.T).as_rotvec()[:, 0]
    return float(np.degrees(np.median(flex)))


def _with(m, *changes: Target, drop: tuple[str, ...] = ()):
    """The map with targets replaced / added (by joint) and some joints removed."""
    new = {t.joint: t for t in changes}
    targets = [new.pop(t.joint, t) for t in m.targets if t.joint not in drop] + list(new.values())
    return dataclasses.replace(m, targets=tuple(targets))


def variants(name: str):
    """The chosen map and the alternatives it was chosen against."""
    from smplcore.skeletons.mapping import sided

    m = skeletons.skeleton_map(name)
    out = {"chosen": m}
    if name == "cmu_daz":
        out["shoulder=Shldr (no offset)"] = _with(m, *sided("shoulder", "lShldr", "rShldr"))
        out["shoulder=0.8 Shldr + 0.2 ForeArm"] = _with(
            m, *sided("shoulder", ("lShldr", "lForeArm"), ("rShldr", "rForeArm"), blend=(0.8, 0.2))
        )
        out["+head"] = _with(m, Target("head", ("head",)))
        out["+head moved (0, 6.4, 5.1) cm, 0.5"] = _with(
            m, Target("head", ("head",), offset=(0, 0.064, 0.051), weight=0.5)
        )
        out["+spine (abdomen, chest)"] = _with(m, Target("spine1", ("abdomen",)), Target("spine3", ("chest",)))
    if name == "cmu_mb":
        out["neck=Neck1"] = _with(m, Target("neck", ("Neck1",)))
        out["all spine (Hips, Spine, Spine1, Neck1, Head)"] = _with(
            m, Target("pelvis", ("Hips",)), Target("spine2", ("Spine",)), Target("spine3", ("Spine1",)),
            Target("neck", ("Neck1",)), Target("head", ("Head",)))  # fmt: skip
        out["wrist=Hand"] = _with(m, *sided("wrist", "LeftHand", "RightHand"))
        out["+head=Head_end (0.5)"] = _with(m, Target("head", ("Head_end",), weight=0.5))
    if name == "cmu_max":
        out["neck=Neck"] = _with(m, Target("neck", ("Neck",)))
        out["wrist=Wrist"] = _with(m, *sided("wrist", "LeftWrist", "RightWrist"))
    if name == "fair":
        out["+spine3, collars (0.5)"] = _with(
            m, Target("spine3", ("Spine3",), weight=0.5), *sided("collar", "LeftShoulder", "RightShoulder", weight=0.5)
        )
        out["head weight 1"] = _with(m, Target("head", ("Head",)))
        out["head moved (0, -2, 5) cm"] = _with(m, Target("head", ("Head",), offset=(0, -0.02, 0.05), weight=0.25))
        out["no head"] = _with(m, drop=("head",))
    return out


def measure(model, targets, frames: int):
    names = list(model.joint_names)
    lo, hi = joint_limits(names[1:24])
    joints = targets.joints
    pick = np.linspace(0, len(joints) - 1, min(frames, len(joints))).round().astype(int)
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = fit.fit_joints(model, joints[pick], list(targets.joint_names), targets.joint_weights, share_betas=True)
    seconds = time.perf_counter() - start
    pose = np.asarray(r.params["body_pose"]).reshape(len(pick), -1, 3)[:, :23]
    deg = np.degrees(pose)

    def joint(n):
        return deg[:, names.index(n) - 1]

    outside = ((pose < lo - 1e-9) | (pose > hi + 1e-9)).any(-1)

    def share(*js):
        return 100.0 * float(outside[:, [names.index(j) - 1 for j in js]].any(-1).mean())

    return (
        r,
        pick,
        {
            "error_mm": 1000 * float(np.mean(r.joint_error)),
            "spine_flex": float(np.median(sum(joint(f"spine{k}")[:, 0] for k in (1, 2, 3)))),
            "spine3": float(np.median(np.linalg.norm(joint("spine3"), axis=-1))),
            "neck": float(np.median(np.linalg.norm(joint("neck"), axis=-1))),
            "neck_flex": float(np.median(joint("neck")[:, 0] + joint("head")[:, 0])),
            "out_spine": share("spine1", "spine2", "spine3"),
            "out_neck": share("neck", "head"),
            "out_elbows": share("left_elbow", "right_elbow"),
            "out_knees": share("left_knee", "right_knee"),
            "seconds": seconds,
        },
    )


def side_view(model, r, targets, pick, frame: int, label: str, size: int = 420):
    """A side view (from the body's left) of one fitted frame, the body turned to face +Z, targets as dots."""
    from PIL import Image, ImageDraw

    from smplcore.render import render_mesh

    params = {k: (np.asarray(v)[frame : frame + 1] if np.asarray(v).shape[0] == len(pick) else np.asarray(v)[:1])
              for k, v in r.params.items()}  # fmt: skip
    out = model(**params)
    go = np.asarray(params["global_orient"]).reshape(3)
    from scipy.spatial.transform import Rotation

    forward = Rotation.from_rotvec(go).as_matrix()[:, 2]
    yaw = np.arctan2(forward[0], forward[2])
    turn = Rotation.from_rotvec([0.0, -yaw, 0.0]).as_matrix()
    verts = np.asarray(out.vertices[0]) @ turn.T
    centre = verts.mean(0)
    dots = targets.joints[pick[frame]] @ turn.T - centre
    img = Image.fromarray(render_mesh(verts - centre, model.faces, width=size, height=size, camera="side",
                                      joints=dots, alpha=0.55))  # fmt: skip
    ImageDraw.Draw(img).text((6, 6), label, fill=(0, 0, 0))
    return img


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mocap", type=Path, default=ROOT.parent / "shared" / "data" / "mocap")
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--render", type=Path, default=None, help="write side views of the chosen maps here (PNG)")
    ap.add_argument("--only", default=None, help="comma-separated skeleton names")
    ap.add_argument("--chosen", action="store_true", help="only the chosen maps (not the alternatives)")
    args = ap.parse_args()
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    panels = []
    print("| skeleton | clip | map | joint error mm | spine flex ° | spine3 ° | neck ° | neck+head flex ° | "
          "outside limits: spine / neck / elbows / knees % | the mocap's own spine flex ° |")  # fmt: skip
    print("|---|---|---|---:|---:|---:|---:|---:|---|---:|")
    for name, clips in CLIPS.items():
        if args.only and name not in args.only.split(","):
            continue
        for clip_path in clips:
            path = args.mocap / clip_path
            if not path.is_file():
                print(f"| {name} | {clip_path} | (absent) |")
                continue
            clip = skeletons.read_bvh(path)
            for label, m in variants(name).items():
                if args.chosen and label != "chosen":
                    continue
                targets = skeletons.to_model_targets(clip, m, model)
                r, pick, s = measure(model, targets, args.frames)
                own = own_spine_flex(clip.without_reference_pose(), name, pick)
                cells = [name, clip_path.split("/")[-1], label, f"{s['error_mm']:.1f}", f"{s['spine_flex']:.0f}",
                         f"{s['spine3']:.0f}", f"{s['neck']:.0f}", f"{s['neck_flex']:.0f}",
                         " / ".join(f"{s[k]:.0f}" for k in ("out_spine", "out_neck", "out_elbows", "out_knees")),
                         f"{own:.0f}"]  # fmt: skip
                print("| " + " | ".join(cells) + " |", flush=True)
                if args.render is not None and label == "chosen" and clip_path == clips[0]:
                    frame = len(pick) // 3
                    panels.append(side_view(model, r, targets, pick, frame, f"{name} {clip_path.split('/')[-1]}"))
    if panels:
        from PIL import Image

        sheet = Image.new("RGB", (sum(p.width for p in panels), max(p.height for p in panels)), "white")
        x = 0
        for p in panels:
            sheet.paste(p, (x, 0))
            x += p.width
        args.render.parent.mkdir(parents=True, exist_ok=True)
        sheet.save(args.render)
        print(f"wrote {args.render}")


if __name__ == "__main__":
    main()
