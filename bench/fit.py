"""Fitting benchmark: smplcore.fit against smplfitter 0.6 and an SMPLify3D-style Adam loop, in one run.

    python bench/fit.py [--quick] [--out bench/FIT_RESULTS.md]

Cases (float32 targets made by the same model, the same targets for every contender):
- vertices → parameters on fake official SMPL and SMPL-X files and the open model: smplcore.fit.fit_vertices
  against smplfitter's BodyFitter (1 and 3 iterations);
- 22 joints → parameters, a 256-frame sequence on the open model: smplcore.fit.fit_joints against a
  joints2smpl-style Adam loop (150 iterations over joint MSE + a pose L2 prior, torch autograd);
- COCO-17 2D keypoints (1 px noise, known camera) on the open model: smplcore.fit.fit_keypoints against an
  SMPLify-style torch LBFGS loop (bench/fit_keypoints_case.py, which also runs alone).
Errors are mean per-vertex (per-joint) distances per body: mean and 95th percentile over bodies.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import fixtures  # noqa: E402

import smplcore  # noqa: E402
from smplcore import fit  # noqa: E402


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip() + f" ({os.cpu_count()} cores visible)"
    except OSError:
        pass
    return platform.processor() or "unknown"


def random_params(model, batch: int, rng: np.random.Generator) -> dict:
    params = {b.name: rng.normal(0, 0.25, (batch, 3 * b.num_joints)) for b in model.setup.spec.pose_blocks}
    params["global_orient"] = rng.normal(0, 0.6, (batch, 3))
    params["betas"] = rng.normal(0, 1, (batch, 10))
    params["transl"] = rng.normal(0, 0.5, (batch, 3))
    return {k: v.astype(np.float32) for k, v in params.items()}


def stats(err: np.ndarray) -> str:
    return f"{1000 * err.mean():.3f} / {1000 * np.percentile(err, 95):.3f}"


def timed(fn):
    start = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - start


def vertices_case(key: str, batch: int, rows: list, rng) -> None:
    files = fixtures.prepare(key)
    opts = {"use_pca": False} if key == "smplx" else {}
    if key == "open":
        model = smplcore.BodyModel(model_type="open", dtype=np.float32)
    else:
        model = smplcore.BodyModel(str(files.file), dtype=np.float32, **opts)
    params = random_params(model, batch, rng)
    target = model(**params).vertices
    fit.fit_vertices(model, target[:2])  # warm-up: builds the cached fitting arrays, as smplfitter's below
    r, dt = timed(lambda: fit.fit_vertices(model, target))
    err = np.linalg.norm(model(**r.params).vertices - target, axis=-1).mean(1)
    ours = batch / dt
    rows.append((f"vertices {key} B={batch}", "smplcore fit_vertices", f"{ours:.1f}", stats(err), "1.0"))
    import torch
    from smplfitter.pt import BodyFitter, BodyModel

    name = {"smpl": "smpl", "open": "smpl", "smplx": "smplx"}[key]
    sf_model = BodyModel(name, files.smplfitter_gender, model_root=str(files.smplfitter_root), num_betas=10)
    fitter = BodyFitter(sf_model)
    tv = torch.as_tensor(target)
    for iters in (1, 3):
        with torch.no_grad():
            fitter.fit(tv[:2], num_iter=iters)  # warm-up
            out, dt = timed(lambda n=iters: fitter.fit(tv, num_iter=n, beta_regularizer=0.0))
            verts = sf_model(out["pose_rotvecs"], out["shape_betas"], out["trans"])["vertices"].numpy()
        err = np.linalg.norm(verts - target, axis=-1).mean(1)
        rate = batch / dt
        rows.append(("", f"smplfitter {iters} iter", f"{rate:.1f}", stats(err), f"{ours / rate:.2f}"))


def adam_joints(model_t, target, iters: int = 150):
    """joints2smpl-style: Adam over pose, betas and translation, joint MSE + a small pose prior."""
    import torch

    b = target.shape[0]
    tgt = torch.as_tensor(target)
    pose = torch.zeros(b, 69, requires_grad=True)
    orient = torch.zeros(b, 3, requires_grad=True)
    betas = torch.zeros(b, 10, requires_grad=True)
    transl = (tgt[:, 0] - model_t(return_verts=False).joints[:, 0]).detach().clone().requires_grad_(True)
    opt = torch.optim.Adam([pose, orient, betas, transl], lr=0.02)
    for _ in range(iters):
        opt.zero_grad()
        j = model_t(body_pose=pose, global_orient=orient, betas=betas, transl=transl, return_verts=False).joints
        loss = ((j[:, :22] - tgt) ** 2).sum(-1).mean() + 1e-4 * (pose**2).mean() + 1e-4 * (betas**2).mean()
        loss.backward()
        opt.step()
    with torch.no_grad():
        j = model_t(body_pose=pose, global_orient=orient, betas=betas, transl=transl, return_verts=False).joints
    return np.linalg.norm(j[:, :22].numpy() - target, axis=-1).mean(1)


def joints_case(frames: int, rows: list, rng) -> None:
    import torch

    model = smplcore.BodyModel(model_type="open", dtype=np.float32)
    base = random_params(model, 1, rng)
    t = np.linspace(0, 1, frames, dtype=np.float32)[:, None]
    params = {
        "global_orient": base["global_orient"] + t * np.float32(1.0),
        "body_pose": base["body_pose"] * (1 + np.sin(6 * t)),
        "betas": np.repeat(base["betas"], frames, 0),
        "transl": base["transl"] + t * np.array([1.0, 0, 0], np.float32),
    }
    target = model(**params).joints[:, :22]
    fit.fit_joints(model, target[:2])  # warm-up
    r, dt = timed(lambda: fit.fit_joints(model, target, share_betas=True))
    ours = frames / dt
    case = f"22 joints, {frames} frames (open)"
    rows.append((case, "smplcore fit_joints", f"{ours:.1f}", stats(r.joint_error), "1.0"))
    r0, dt0 = timed(lambda: fit.fit_joints(model, target, share_betas=True, max_iter=0))
    rows.append(("", "smplcore fit_joints max_iter=0 (closed form)", f"{frames / dt0:.1f}", stats(r0.joint_error), ""))
    model_t = smplcore.create(model_type="open")
    err, dt = timed(lambda: adam_joints(model_t, target))
    rate = frames / dt
    rows.append(("", "Adam 150 iterations (torch)", f"{rate:.1f}", stats(err), f"{ours / rate:.2f}"))
    rows[-2] = (*rows[-2][:4], f"{frames / dt0 / rate:.2f}")
    del torch


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small batches (a smoke test)")
    parser.add_argument("--large", nargs="*", default=["smpl"], help="models also run at B = 1024")
    parser.add_argument("--out", default=str(Path(__file__).resolve().parent / "FIT_RESULTS.md"))
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    rows: list = []
    batch = 8 if args.quick else 128
    for key in ("smpl", "smplx", "open"):
        vertices_case(key, batch, rows, rng)
        print(rows[-3:], flush=True)
    for key in args.large:
        vertices_case(key, 32 if args.quick else 1024, rows, rng)
        print(rows[-3:], flush=True)
    joints_case(32 if args.quick else 256, rows, rng)
    print(rows[-2:], flush=True)
    from fit_keypoints_case import keypoints_case  # the COCO-17 2D case (also runnable alone)

    keypoints_case(8 if args.quick else 32, rows, np.random.default_rng(0))
    print(rows[-2:], flush=True)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    lines = [
        "# Fitting benchmark",
        "",
        f"`python bench/fit.py{' --quick' if args.quick else ''}` on {cpu_name()},",
        "float32 targets from the same model,",
        f"smplcore {smplcore.__version__}, NumPy {np.__version__}. Errors: mean distance per body (mm), mean / 95th",
        "percentile over bodies. Ratio: smplcore's fits/s over the contender's (higher: smplcore faster).",
        f"Peak resident memory of the whole run: {peak:.0f} MB.",
        "",
        "| case | contender | fits/s | error mm (mean / p95) | smplcore × |",
        "|---|---|---|---|---|",
    ]
    lines += [f"| {a} | {b} | {c} | {d} | {e} |" for a, b, c, d, e in rows]
    Path(args.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
