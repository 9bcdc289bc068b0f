"""2D fitting on held-out real motion capture: CMU subject 06 (basketball, walking), which the open pose prior
never saw, projected through cameras as a detector would report it, fitted with fit_keypoints.

    python bench/fit2d_real.py [--images 60] [--step 30] [--convention coco17] [--gmm PATH] [--out ...]

Needs the shared mocap (``../shared/data/mocap/``, or ``SMPLCORE_MOCAP``); says so and stops without it.

1. **Truth.** Each clip of ``cmu_mb_jonathanalderson/06_*.bvh.gz``, every ``--step``-th frame (frame 0, the
   T-pose, dropped), read by ``smplcore.skeletons.read_bvh`` and mapped by its ``cmu_mb`` skeleton map to the
   open model's joints; ``fit_joints`` (joint limits on, one shape per clip) gives a body per frame: the
   truth is that body (its COCO-17 keypoints), a real motion on a body the model can take.
2. **Views** (one image per body, seeded). ``full``: a level camera (pitch −6° to 9°) 3-5 m away at a random
   azimuth around the person, f = 900-1500 px, the image framed around the body. ``hips`` / ``knees``: a
   camera 1.8-3.5 m away aimed at the chest, the image's bottom edge through the hips (± 3 cm) or knees:
   an upper-body photo, a person cut by the image's edge. Every keypoint gets 2-5 px of noise and a
   confidence U(0.5, 1); 10 % are dropped (confidence U(0, 0.3), moved 15 px); keypoints outside the
   image are OpenPose's zeros in half of the images, in the others a MediaPipe-like guess (the truth
   ± 30 px, confidence U(0.05, 0.5)).
3. **Fit**: ``fit_keypoints`` with the true intrinsics, the image's size known (``Camera(image_size=...)``).
   The "no upright, no image size" rows switch off this wave's upright prior and the image-edge rule.

Measures (over the images; the 3D keypoints are COCO-17 in camera space): PA-MPJPE over the 17 points and
over the 13 of the head, arms and hips ("upper"); depth-order errors: pairs of the 12 limb points
(shoulders to ankles) more than 10 cm apart in depth whose front/back order the fit flips; the torso's
lean error (pelvis → neck direction against the truth's); the pelvis' depth error; flags: not converged,
implausible (joint limits), warnings (legs not visible); time per image.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import smplcore
from smplcore import fit
from smplcore import keypoints as kp

HERE = Path(__file__).resolve().parent
MOCAP = Path(os.environ.get("SMPLCORE_MOCAP", HERE.parents[1] / "shared" / "data" / "mocap"))
UP = np.array([0.0, 1.0, 0.0])


def truth(model, step: int) -> dict[str, np.ndarray]:
    """The held-out bodies (see the module docstring)."""
    from smplcore import skeletons

    parts = []
    for path in sorted((MOCAP / "cmu_mb_jonathanalderson").glob("06_*.bvh.gz")):
        t = skeletons.to_model_targets(skeletons.read_bvh(path), "cmu_mb", model, drop_reference_pose=True)
        rows = np.arange(0, len(t.joints), step)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = fit.fit_joints(model, t.joints[rows], list(t.joint_names), t.joint_weights, share_betas=True)
        parts.append({k: np.asarray(v, np.float64) for k, v in r.params.items()})
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def _camera_looking(eye: np.ndarray, target: np.ndarray, pitch: float) -> tuple[np.ndarray, np.ndarray]:
    """World-to-camera R, t (OpenCV axes) of a camera at ``eye`` looking level at ``target``, pitched down."""
    z = target - eye
    z[1] = 0.0
    z = np.cos(pitch) * z / np.linalg.norm(z) + np.sin(pitch) * -UP
    x = np.cross(-UP, z)
    x /= np.linalg.norm(x)
    rot = np.stack([x, np.cross(z, x), z])
    return rot, -rot @ eye


def views(model, params, kind: str, convention: str, rng: np.random.Generator) -> list[dict]:
    """One image per body (see the module docstring)."""
    joints = np.asarray(model(**params).joints, np.float64)
    points = kp.convert(joints, model, convention)[0]
    coco = kp.convert(joints, model, "coco17")[0]
    names = kp.layout(convention).names
    out = []
    for b in range(len(points)):
        pts, az = points[b], rng.uniform(0, 2 * np.pi)
        if kind == "full":
            dist, f = rng.uniform(3, 5), rng.uniform(900, 1500)
            target = np.array([joints[b, 0, 0], rng.uniform(0.9, 1.7), joints[b, 0, 2]])
            rot, t = _camera_looking(
                target + dist * np.array([np.sin(az), 0, np.cos(az)]), target, rng.uniform(-0.1, 0.15)
            )
            uv = (pts @ rot.T + t)[:, :2] / (pts @ rot.T + t)[:, 2:] * f
            half = float(np.ceil(np.abs(uv).max() * 1.15))
            size, centre = (2 * half, 2 * half), np.array([half, half])
        else:
            cut = ("left_hip", "right_hip") if kind == "hips" else ("left_knee", "right_knee")
            dist, f = rng.uniform(1.8, 3.5), rng.uniform(900, 1500)
            chest = 0.5 * (pts[names.index("left_shoulder")] + pts[names.index("right_shoulder")])
            eye = chest + dist * np.array([np.sin(az), 0, np.cos(az)]) + [0, rng.uniform(-0.1, 0.1), 0]
            rot, t = _camera_looking(eye, chest, rng.uniform(-0.05, 0.1))
            uv = (pts @ rot.T + t)[:, :2] / (pts @ rot.T + t)[:, 2:] * f
            edge = np.mean([uv[names.index(n), 1] for n in cut]) + rng.uniform(-0.03, 0.03) * f / dist
            extent = uv.max(0) - uv.min(0)
            top = uv[:, 1].min() - 0.15 * extent[1]
            left, right = uv[:, 0].min() - 0.2 * extent[0], uv[:, 0].max() + 0.2 * extent[0]
            size, centre = (float(np.ceil(right - left)), float(np.ceil(edge - top))), np.array([-left, -top])
        uv = uv + centre
        noisy = uv + rng.normal(0, rng.uniform(2, 5), uv.shape)
        conf = rng.uniform(0.5, 1.0, len(uv))
        drop = rng.random(len(uv)) < 0.1
        conf[drop] = rng.uniform(0.0, 0.3, drop.sum())
        noisy[drop] += rng.normal(0, 15, (drop.sum(), 2))
        outside = np.any((uv < 0) | (uv > np.array(size)), axis=1)
        if outside.any() and rng.random() < 0.5:  # OpenPose: zeros
            noisy[outside], conf[outside] = 0.0, 0.0
        elif outside.any():  # MediaPipe-like: a guess with a middling visibility
            noisy[outside] = uv[outside] + rng.normal(0, 30, (outside.sum(), 2))
            conf[outside] = rng.uniform(0.05, 0.5, outside.sum())
        out.append({"keypoints": np.c_[noisy, conf], "f": f, "size": size, "centre": centre,
                    "coco": coco[b] @ rot.T + t, "joints": joints[b] @ rot.T + t})  # fmt: skip
    return out


def _pa(x: np.ndarray, y: np.ndarray) -> float:
    x0, y0 = x - x.mean(0), y - y.mean(0)
    u, s, vt = np.linalg.svd(y0.T @ x0)
    d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    return float(np.linalg.norm(np.sum(s * np.diag(d)) / np.sum(y0 * y0) * y0 @ (u @ d @ vt) - x0, axis=1).mean())


def _torso(j: np.ndarray) -> np.ndarray:
    v = j[12] - j[0]
    return v / np.linalg.norm(v)


def measure(model, view: dict, r, warned: bool) -> dict:
    got = np.asarray(model(**r.params).joints, np.float64)[0]
    k3 = kp.convert(got[None], model, "coco17")[0][0]
    gt = view["coco"]
    i, j = np.triu_indices(12, 1)
    zg, zf = gt[5:, 2], k3[5:, 2]
    apart = np.abs(zg[i] - zg[j]) > 0.1
    flipped = apart & (np.sign(zg[i] - zg[j]) != np.sign(zf[i] - zf[j]))
    return {
        "pa": 1000 * _pa(gt, k3),
        "upper": 1000 * _pa(gt[:13], k3[:13]),
        "order": flipped.sum() / max(apart.sum(), 1),
        "lean": np.degrees(np.arccos(np.clip(_torso(view["joints"]) @ _torso(got), -1, 1))),
        "dz": abs(got[0, 2] - view["joints"][0, 2]) / view["joints"][0, 2],
        "converged": bool(r.converged[0]),
        "plausible": r.plausibility is None or bool(r.plausibility.plausible[0]),
        "warned": warned,
    }


def run_case(model, scenes: list[dict], convention: str, new_rules: bool, **options) -> tuple[dict, float]:
    rows = []
    start = time.perf_counter()
    for v in scenes:
        size = {"image_size": v["size"]} if new_rules else {}
        camera = fit.Camera(focal=v["f"], center=v["centre"], **size)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            r = fit.fit_keypoints(model, v["keypoints"][None], convention, camera,
                                  **({} if new_rules else {"upright": 0.0}), **options)  # fmt: skip
        rows.append(measure(model, v, r, any(issubclass(w.category, fit.PartialViewWarning) for w in caught)))
    seconds = (time.perf_counter() - start) / len(scenes)
    return {k: np.array([row[k] for row in rows]) for k in rows[0]}, seconds


def row(kind: str, label: str, a: dict, seconds: float) -> str:
    return (
        f"| {kind} | {label} | {a['pa'].mean():.1f} / {np.percentile(a['pa'], 95):.0f} | {a['upper'].mean():.1f} | "
        f"{100 * a['order'].mean():.1f} % | {np.median(a['lean']):.1f}° / {np.percentile(a['lean'], 90):.0f}° | "
        f"{100 * np.median(a['dz']):.0f} % / {100 * np.percentile(a['dz'], 90):.0f} % | "
        f"{(~a['converged']).sum()} / {(~a['plausible']).sum()} / {a['warned'].sum()} | {seconds:.2f} |"
    )


def main() -> None:
    sys.path.insert(0, str(HERE))
    from fit import cpu_name

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--images", type=int, default=60)
    parser.add_argument("--step", type=int, default=30, help="every step-th mocap frame (120 fps)")
    parser.add_argument("--convention", default="coco17")
    parser.add_argument("--gmm", default=None, help="a GMMPrior .npz (means, covars, weights) to compare")
    parser.add_argument("--out", default=str(HERE / "FIT2D_RESULTS.md"))
    args = parser.parse_args()
    if not (MOCAP / "cmu_mb_jonathanalderson").is_dir():
        sys.exit(f"bench/fit2d_real.py: the shared mocap is not at {MOCAP} (set SMPLCORE_MOCAP); nothing measured")
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    bodies = truth(model, args.step)
    pick = np.linspace(0, len(bodies["transl"]) - 1, min(args.images, len(bodies["transl"]))).astype(int)
    bodies = {k: v[pick] for k, v in bodies.items()}
    setups = [("no upright, no image size", False, {}), ("this wave (defaults)", True, {})]
    if args.gmm:
        with np.load(args.gmm, allow_pickle=False) as d:
            gmm = fit.GMMPrior.from_arrays(d["means"], d["covars"], d["weights"], args.gmm)
        setups.append(("+ open GMM prior (gmm_weight 1e-4)", True, {"gmm": gmm}))
    lines = []
    for kind in ("full", "hips", "knees"):
        scenes = views(model, bodies, kind, args.convention, np.random.default_rng(0))
        for label, new_rules, options in setups:
            a, seconds = run_case(model, scenes, args.convention, new_rules, **options)
            lines.append(row(kind, label, a, seconds))
            print(lines[-1], flush=True)
    section = [
        f"## Real motion capture ({args.convention})",
        "",
        f"`python bench/fit2d_real.py --images {args.images} --convention {args.convention}"
        f"{' --gmm ' + Path(args.gmm).name if args.gmm else ''}` on {cpu_name()}, load average "
        f"{os.getloadavg()[0]:.1f}. The setup is in the script's docstring ({len(pick)} bodies of held-out CMU "
        "subject 06, one image each per case).",
        "",
        "| case | fit | PA-MPJPE mean / p95 (mm) | upper PA (mm) | depth-order errors | lean error median / p90 | "
        "pelvis depth error median / p90 | not converged / implausible / legs warned | s per image |",
        "|---|---|---|---|---|---|---|---|---|",
        *lines,
    ]
    out = Path(args.out)
    old = out.read_text() if out.exists() else ""
    marker = f"## Real motion capture ({args.convention})"
    if marker in old:  # replace this convention's section, keep the rest
        start = old.index(marker)
        end = old.find("\n## ", start + 1)
        old = old[:start] + (old[end + 1 :] if end >= 0 else "")
    out.write_text(old.rstrip("\n") + "\n\n" + "\n".join(section) + "\n")
    print("\n".join(section))


if __name__ == "__main__":
    main()
