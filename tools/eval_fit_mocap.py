"""Fit the held-out subjects' real mocap with ``fit_joints`` and report quality and speed, per prior setting.

The subjects that tools/train_pose_prior.py holds out (never seen by the open pose prior) are fitted as a user
would: BVH → ``smplcore.skeletons.to_model_targets`` (skeleton map, metres, Y up) → ``fit_joints`` on the open
model, one shape per clip (``share_betas=True``), at about 30 fps. Three settings: no priors (``joint_limits=0``),
the default anatomical limits, and the limits with the open pose prior (``gmm=GMMPrior.open()``). Reported:
joint error (mean, 95th percentile), how often the fitted poses are outside the joint limits (by more than 5°;
per joint), jitter (mean |second difference| of the fitted joints over the mocap's own), LM iterations, fits/s,
and the open prior's mean cost of the fitted poses::

    python tools/eval_fit_mocap.py --report build/eval_fit_mocap.json
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
sys.path.insert(0, str(ROOT / "src"))

from train_pose_prior import HELD_OUT, limit_report, subject_of  # noqa: E402

import smplcore  # noqa: E402
from smplcore import fit  # noqa: E402
from smplcore.skeletons import read_bvh, to_model_targets  # noqa: E402


def settings() -> dict[str, dict]:
    return {
        "no priors": {"joint_limits": 0.0, "gmm": None},
        "limits only": {"gmm": None},
        "default (limits; open GMM where bones are out of reach)": {},
        "limits + open GMM": {"gmm": fit.GMMPrior.open()},
    }


def jitter(points: np.ndarray) -> float:
    """Mean |second difference| (metres per frame²) of (T, n, 3) positions."""
    return float(np.nanmean(np.linalg.norm(points[2:] - 2 * points[1:-1] + points[:-2], axis=-1)))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mocap", type=Path, default=ROOT.parent / "shared" / "data" / "mocap")
    ap.add_argument("--fps", type=float, default=30.0)
    ap.add_argument("--max-clips", type=int, default=None, help="only the first n held-out clips")
    ap.add_argument("--report", type=Path, default=None)
    args = ap.parse_args(argv)
    rows = [r for r in csv.DictReader(open(args.mocap / "index.csv")) if subject_of(r["file"]) in HELD_OUT]
    rows = rows[: args.max_clips]
    model = smplcore.BodyModel(model_type="open")
    names = list(model.joint_names[1:24])
    gmm = fit.GMMPrior.open()
    clips = []
    for row in rows:
        clip = read_bvh(args.mocap / row["file"]).without_reference_pose()
        step = max(1, int(round(clip.fps / args.fps)))
        targets = to_model_targets(clip.frames(slice(None, None, step)), model=model)
        clips.append((row["file"], targets))
    report: dict = {
        "subjects": sorted({subject_of(f) for f, _ in clips}),
        "clips": len(clips),
        "frames": sum(len(t.joints) for _, t in clips),
        "fps": args.fps,
        "settings": {},
    }
    for label, options in settings().items():
        poses, errors, iters, seconds, jit, jit_ref = [], [], [], 0.0, [], []
        for _, t in clips:
            joints, jnames, weights = t
            start = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                r = fit.fit_joints(model, joints, jnames, weights, share_betas=True, **options)
            seconds += time.perf_counter() - start
            ids = [model.joint_names.index(n) for n in jnames]
            fitted = np.asarray(model(**r.params).joints, np.float64)[:, ids]
            errors.append(np.linalg.norm(fitted - joints, axis=-1).ravel())
            poses.append(np.asarray(r.params["body_pose"], np.float64))
            iters.append(r.iterations)
            jit.append(jitter(fitted) * len(joints))
            jit_ref.append(jitter(joints) * len(joints))
        poses_all = np.concatenate(poses)
        err = np.concatenate(errors)
        err = err[np.isfinite(err)]
        best, res, _ = gmm.residuals(poses_all)
        frames = len(poses_all)
        limits = limit_report(poses_all, names)
        top = dict(sorted(limits["per_joint"].items(), key=lambda kv: -kv[1])[:6])
        report["settings"][label] = {
            "joint_error_mean_mm": round(float(err.mean() * 1000), 2),
            "joint_error_p95_mm": round(float(np.percentile(err, 95) * 1000), 2),
            "poses_outside_limits": limits["poses_outside"],
            "worst_joints_outside": top,
            "jitter_over_mocap": round(sum(jit) / sum(jit_ref), 3),
            "iterations_mean": round(float(np.mean(iters)), 1),
            "fits_per_second": round(frames / seconds, 1),
            "open_prior_cost_mean": round(float(np.mean(0.5 * np.sum(res**2, 1) + gmm.penalty[best])), 2),
        }
        print(label, json.dumps(report["settings"][label]), flush=True)
    if args.report is not None:
        args.report.parent.mkdir(parents=True, exist_ok=True)
        args.report.write_text(json.dumps(report, indent=1))
    print(json.dumps({k: v for k, v in report.items() if k != "settings"}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
