"""The COCO-17 2D-keypoint case of bench/fit.py, runnable alone:

    python bench/fit_keypoints_case.py [--images 32] [--out bench/FIT2D_RESULTS.md]

Synthetic open-model bodies (knees and elbows bent the right way, arms lowered, body-pose noise of
0.1 rad on every component, betas N(0, 0.5), facing the camera ±15°, 3–5 m away) seen by a known camera
(f = 1000 px, 1000 × 1000 image), COCO-17 keypoints with 1 px Gaussian noise, confidence 1.
Contenders: smplcore.fit.fit_keypoints, and an SMPLify-style loop in torch (the same data term:
Geman–McClure σ = 100 px on the reprojections; pose and shape L2 priors and SMPLify's exp elbow/knee
prior; stage 1 translation + global orientation, then three stages of decreasing prior weights, each a
torch.optim.LBFGS run of 30 iterations with strong-Wolfe line search, all images in one batch).
Errors: reprojection (px, mean over keypoints) and PA-MPJPE over the 17 COCO points in 3D (mm).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

import smplcore
from smplcore import fit
from smplcore import keypoints as kp

CAMERA = fit.Camera(focal=1000.0, center=(500.0, 500.0))


def synthetic_params(model, count: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """The bodies of the module docstring: natural poses, 3-5 m in front of the camera."""
    names = list(model.joint_names)

    def col(joint, axis):
        return (names.index(joint) - 1) * 3 + axis

    pose = rng.normal(0, 0.1, (count, 69))
    for side, s in (("left", 1.0), ("right", -1.0)):
        pose[:, col(f"{side}_knee", 0)] = rng.uniform(0.1, 1.0, count)
        pose[:, col(f"{side}_elbow", 1)] = -s * rng.uniform(0.2, 1.3, count)
        pose[:, col(f"{side}_shoulder", 2)] = -s * rng.uniform(0.3, 1.1, count)
    params = {
        "global_orient": np.tile([np.pi, 0.0, 0.0], (count, 1)) + rng.normal(0, 0.25, (count, 3)),
        "body_pose": pose,
        "betas": rng.normal(0, 0.5, (count, 10)),
        "transl": np.c_[rng.normal(0, 0.3, count), rng.normal(0, 0.2, count), rng.uniform(3.0, 5.0, count)],
    }
    return params


def synthetic(model, count: int, rng: np.random.Generator):
    params = synthetic_params(model, count, rng)
    j3 = kp.convert(np.asarray(model(**params).joints, np.float64), model, "coco17")[0]
    uv = CAMERA.project(j3) + rng.normal(0, 1.0, j3.shape[:2] + (2,))
    return params, np.concatenate([uv, np.ones(uv.shape[:2] + (1,))], -1), j3


def pa_mpjpe(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = []
    for x, y in zip(a, b, strict=True):
        x0, y0 = x - x.mean(0), y - y.mean(0)
        u, s, vt = np.linalg.svd(y0.T @ x0)
        d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
        scale = np.sum(s * np.diag(d)) / np.sum(y0 * y0)
        out.append(np.linalg.norm(scale * y0 @ (u @ d @ vt) - x0, axis=1).mean())
    return np.asarray(out)


def smplify_lbfgs(model_t, keypoints: np.ndarray, iters: int = 30):
    """An SMPLify-style fit in torch (see the module docstring); returns (B, 17, 3) keypoints in 3D."""
    import torch

    plan = kp.plan(model_t, "coco17")
    first, second = torch.as_tensor(plan.first), torch.as_tensor(plan.second)
    names = list(model_t.joint_names)
    f, c = torch.tensor(CAMERA.focal), torch.tensor(CAMERA.center)
    target = torch.as_tensor(keypoints[..., :2], dtype=torch.float32)
    conf = torch.as_tensor(keypoints[..., 2], dtype=torch.float32)
    b = len(keypoints)
    pose = torch.zeros(b, 69, requires_grad=True)
    betas = torch.zeros(b, 10, requires_grad=True)
    orient = torch.tensor([[np.pi, 0.0, 0.0]] * b, dtype=torch.float32, requires_grad=True)
    # depth from the torso: shoulders-to-hips distance in the image against the rest body's
    with torch.no_grad():
        rest = model_t(global_orient=orient).joints
        kps = 0.5 * (rest[:, first] + rest[:, second])
        sh, hp = kps[:, 5:7].mean(1), kps[:, 11:13].mean(1)
        depth = f[0] * (sh - hp).norm(dim=-1) / (target[:, 5:7].mean(1) - target[:, 11:13].mean(1)).norm(dim=-1)
        centre = (target[:, [5, 6, 11, 12]].mean(1) - c) / f * depth[:, None]
        transl0 = torch.cat([centre, depth[:, None]], 1) - kps[:, [5, 6, 11, 12]].mean(1)
    transl = transl0.clone().requires_grad_(True)
    bend = torch.tensor([(names.index(n) - 1) * 3 + a for n, a in
                         (("left_elbow", 1), ("right_elbow", 1), ("left_knee", 0), ("right_knee", 0))])  # fmt: skip
    signs = torch.tensor([1.0, -1.0, -1.0, -1.0])

    def loss_fn(w_pose: float, w_shape: float, w_bend: float, joints_used):
        out = model_t(body_pose=pose, betas=betas, global_orient=orient, transl=transl)
        k3 = 0.5 * (out.joints[:, first] + out.joints[:, second])
        uv = k3[..., :2] / k3[..., 2:] * f + c
        e2 = ((uv - target) ** 2).sum(-1)
        data = (conf * joints_used * 100.0**2 * e2 / (100.0**2 + e2)).sum()
        prior = w_pose * (pose**2).sum() + w_shape * (betas**2).sum()
        prior = prior + w_bend * torch.exp(pose[:, bend] * signs).pow(2).sum()
        return data + prior

    def run(params, *weights):
        opt = torch.optim.LBFGS(params, lr=1.0, max_iter=iters, line_search_fn="strong_wolfe")

        def closure():
            opt.zero_grad()
            loss = loss_fn(*weights)
            loss.backward()
            return loss

        opt.step(closure)

    torso = torch.zeros(17)
    torso[[5, 6, 11, 12]] = 1.0
    run([transl, orient], 0.0, 0.0, 0.0, torso)
    for w_pose, w_shape, w_bend in ((404.0, 100.0, 300.0), (57.4, 50.0, 100.0), (4.78, 5.0, 30.0)):
        run([pose, betas, orient, transl], w_pose, w_shape, w_bend, torch.ones(17))
    with torch.no_grad():
        out = model_t(body_pose=pose, betas=betas, global_orient=orient, transl=transl)
        k3 = 0.5 * (out.joints[:, first] + out.joints[:, second])
    return k3.numpy().astype(np.float64)


def keypoints_case(count: int, rows: list, rng: np.random.Generator) -> dict:
    """Append the case's rows (case, contender, fits/s, error, ratio) and return the raw numbers."""
    model = smplcore.BodyModel(model_type="open", dtype=np.float32)
    _, keypoints, j3 = synthetic(model, count, rng)
    start, cpu = time.perf_counter(), time.process_time()
    r = fit.fit_keypoints(model, keypoints, camera=CAMERA, **GMM)
    ours_dt = (time.perf_counter() - start) / count
    ours_cpu = (time.process_time() - cpu) / count
    got = kp.convert(np.asarray(model(**r.params).joints, np.float64), model, "coco17")[0]
    ours_pa = pa_mpjpe(j3, got)
    case = f"COCO-17 2D, {count} images (open, 1 px noise)"

    def err(pa, rep):
        return f"PA {1000 * pa.mean():.1f} / {1000 * np.percentile(pa, 95):.1f}; reproj {rep.mean():.2f} px"

    rows.append((case, "smplcore fit_keypoints", f"{1 / ours_dt:.1f} ({ours_dt:.3f} s/img; CPU {ours_cpu:.3f} s)",
                 err(ours_pa, r.reprojection_error), "1.0"))  # fmt: skip
    numbers = {"ours_s": ours_dt, "ours_pa": ours_pa, "ours_rep": r.reprojection_error, "converged": r.converged}
    try:
        import torch  # noqa: F401
    except ImportError:
        return numbers
    model_t = smplcore.create(model_type="open")
    start, cpu = time.perf_counter(), time.process_time()
    k3 = smplify_lbfgs(model_t, keypoints)
    theirs_dt = (time.perf_counter() - start) / count
    theirs_cpu = (time.process_time() - cpu) / count
    rep = np.linalg.norm(CAMERA.project(k3) - keypoints[..., :2], axis=-1).mean(1)
    pa = pa_mpjpe(j3, k3)
    rows.append(("", "SMPLify-style LBFGS (torch, 4 x 30 it)",
                 f"{1 / theirs_dt:.1f} ({theirs_dt:.3f} s/img; CPU {theirs_cpu:.3f} s)",
                 err(pa, rep), f"{theirs_dt / ours_dt:.2f}"))  # fmt: skip
    numbers.update(theirs_s=theirs_dt, theirs_pa=pa, theirs_rep=rep)
    return numbers


GMM: dict[str, str] = {}  # fit_keypoints' gmm= (--gmm)


def main() -> None:
    import argparse

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from fit import cpu_name

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--images", type=int, default=32)
    parser.add_argument("--gmm", default=None, help='a pose mixture for fit_keypoints ("open", a gmm_08.pkl path)')
    parser.add_argument("--out", default=str(Path(__file__).resolve().parent / "FIT2D_RESULTS.md"))
    args = parser.parse_args()
    if args.gmm:
        GMM["gmm"] = args.gmm
    rows: list = []
    numbers = keypoints_case(args.images, rows, np.random.default_rng(0))
    lines = [
        "# 2D keypoint fitting benchmark",
        "",
        f"Load average at the start: {os.getloadavg()[0]:.1f} (the machine is shared; wall times vary with it).",
        "",
        f"`python bench/fit_keypoints_case.py --images {args.images}` on {cpu_name()}, "
        f"smplcore {smplcore.__version__}, NumPy {np.__version__}. The setup is in the script's docstring.",
        f"PA-MPJPE mean / 95th percentile over images (mm). smplcore converged on "
        f"{int(numbers['converged'].sum())} of {args.images} images.",
        "",
        "| case | contender | fits/s | error | smplcore × |",
        "|---|---|---|---|---|",
    ]
    lines += [f"| {a} | {b} | {c} | {d} | {e} |" for a, b, c, d, e in rows]
    out = Path(args.out)
    old = out.read_text() if out.exists() else ""
    keep = old[old.index("## Focal length estimation") :] if "## Focal length estimation" in old else ""
    out.write_text("\n".join(lines) + "\n" + ("\n" + keep if keep else ""))  # keeps fit_focal_case.py's section
    print("\n".join(lines))


if __name__ == "__main__":
    main()
