"""Train smplcore's open pose prior (src/smplcore/data/pose_prior_open.npz) from the shared mocap.

Re-runnable and deterministic (fixed seeds, clips in index.csv order)::

    python tools/train_pose_prior.py                      # all 190 clips, writes the shipped file
    python tools/train_pose_prior.py --quick --out /tmp/p.npz   # 6 clips, a minute: a smoke test

Steps:

1. Each clip of ``../shared/data/mocap`` (``--mocap``; its README.md describes the five skeleton families) is
   read at about ``--fps`` (30) frames per second, the reference-pose frame 0 dropped where ``index.csv`` says
   there is one.
2. Retarget (tools/pose_prior_retarget.py): the open model's rest skeleton (mean shape) is re-posed with the
   mocap's motion (limb directions, rigid-part rotations; the head, wrists and toes calibrated per performer:
   each one's mean posture of these over all of their clips is taken as the model's rest one) and
   ``smplcore.fit.fit_joints`` finds the body pose reaching it.
3. Split by performer: CMU subject = the number before the underscore; the four FAIR clips are one more
   subject. :data:`HELD_OUT` subjects are used only for validation.
4. A Gaussian mixture (scikit-learn, a tool-time dependency only: the shipped file is read by NumPy) over the
   63 body-pose values of the 21 body joints is fitted for each ``--components`` K on the training subjects;
   the K with the best held-out mean log-likelihood per pose is shipped (trained on the training subjects
   only, so the held-out subjects stay unseen by the prior). The two hand joints of SMPL's 23 (no CMU hand
   data) get an independent zero-mean Gaussian of 0.3 rad per value: the shipped mixture covers 69 values, and
   ``GMMPrior.marginal(63)`` gives the 21-joint models' (SMPL+H, SMPL-X).
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
sys.path.insert(0, str(ROOT / "src"))

from pose_prior_retarget import Motion, calibration, clip_motion, model_rest, retarget  # noqa: E402

import smplcore  # noqa: E402
from smplcore.fit.priors import joint_limits  # noqa: E402

#: Subjects held out for validation: a varied Daz-friendly performer (walk, run, jump, punch, wash),
#: a MotionBuilder one with his own bone lengths (basketball), and an activity absent from training (Indian dance).
HELD_OUT = ("02", "06", "94")
QUICK_CLIPS = (
    "cmu_mb_jonathanalderson/05_01.bvh.gz", "cmu_daz_ateliercircle/07_01.bvh.gz",
    "cmu_daz_ateliercircle/13_29.bvh.gz", "fair_animateddrawings/dab.bvh.gz",
    "cmu_mb_jonathanalderson/06_01.bvh.gz", "cmu_daz_ateliercircle/02_01.bvh.gz",
)  # fmt: skip
BODY = 63  # 21 body joints (SMPL+H / SMPL-X); SMPL's 23 add the two hands
HAND_STD = 0.3  # rad: the hands' independent Gaussian (no hand data in these releases)
REG_COVAR = np.radians(3.0) ** 2  # variance floor per value: the retarget's own noise, and values the data never moves
LIMIT_TOL = np.radians(5.0)  # a pose is "outside the limits" when a value is past its bound by more than this
LICENCE = (
    "Trained by smplcore's tools/train_pose_prior.py on motion capture: 186 clips of the CMU Graphics Lab Motion "
    "Capture Database (mocap.cs.cmu.edu) in Bruce Hahne's (cgspeed) BVH conversions, and 4 FAIR clips of "
    "facebookresearch/AnimatedDrawings (MIT licence, (c) Meta Platforms, Inc. and affiliates). CMU's terms allow "
    "use in research and commercial products, not reselling the data itself; this file holds only the mixture's "
    'parameters, no motion. CMU asks for this acknowledgement: "The data used in this project was obtained from '
    'mocap.cs.cmu.edu. The database was created with funding from NSF EIA-0196217."'
)


def subject_of(path: str) -> str:
    """The performer of a clip: the CMU subject number, or "fair" for the AnimatedDrawings actor."""
    return "fair" if path.startswith("fair_") else Path(path).name.split("_")[0]


def read_index(mocap: Path, quick: bool) -> list[dict[str, str]]:
    rows = list(csv.DictReader(open(mocap / "index.csv", newline="")))
    return [r for r in rows if r["file"] in QUICK_CLIPS] if quick else rows


def retarget_all(mocap: Path, rows, fps: float, log) -> tuple[list[dict], dict]:
    """Read, calibrate (per performer, on all of the performer's clips) and fit every clip."""
    motions: list[tuple[dict, Motion]] = []
    for i, row in enumerate(rows):
        motion = clip_motion(mocap / row["file"], fps, row["frame0_is_reference_pose"] == "yes")
        motions.append((row, motion))
        log(f"read {i + 1}/{len(rows)} {row['file']}: {len(motion.frames)} frames ({motion.family})")
    calib = {}  # per performer: the head, wrists and toes of each performer's skeleton have their own rest frames
    for subject in sorted({subject_of(row["file"]) for row, _ in motions}):
        calib[subject] = calibration([m for row, m in motions if subject_of(row["file"]) == subject])
    model = smplcore.BodyModel(model_type="open")
    rest = model_rest(model)
    clips = []
    for i, (row, motion) in enumerate(motions):
        r, _ = retarget(model, rest, motion, calib[subject_of(row["file"])])
        clips.append({"file": row["file"], "subject": subject_of(row["file"]), "category": row["category"], "fit": r})
        log(f"fit {i + 1}/{len(motions)} {row['file']}: {len(r.frames)} frames, {r.iterations} it, "
            f"{r.seconds:.1f} s, error {r.joint_error.mean() * 1000:.2f} mm")  # fmt: skip
    return clips, calib


def limit_report(poses: np.ndarray, names: list[str]) -> dict:
    """How often (T, 69) poses are outside :data:`smplcore.fit.priors.JOINT_LIMITS` (by more than LIMIT_TOL)."""
    lo, hi = joint_limits(names)
    th = poses.reshape(len(poses), -1, 3)
    out = ((th < lo - LIMIT_TOL) | (th > hi + LIMIT_TOL)).any(-1)  # (T, J)
    per = {n: round(float(v), 4) for n, v in zip(names, out.mean(0)) if v > 0}
    return {"poses_outside": round(float(out.any(1).mean()), 4), "per_joint": per}


def fit_mixtures(train: np.ndarray, held: np.ndarray, ks: list[int], seed: int, log) -> tuple[dict, dict]:
    """Mixtures of each K over the 63 body values; held-out and training mean log-likelihood per pose."""
    from sklearn.mixture import GaussianMixture

    fitted, scores = {}, {}
    for k in ks:
        start = time.perf_counter()
        gmm = GaussianMixture(k, covariance_type="full", reg_covar=REG_COVAR, max_iter=300, n_init=1,
                              init_params="k-means++", random_state=seed).fit(train[:, :BODY])  # fmt: skip
        scores[k] = {
            "held_out_loglik": round(float(gmm.score(held[:, :BODY])), 3),
            "train_loglik": round(float(gmm.score(train[:, :BODY])), 3),
            "converged": bool(gmm.converged_),
            "seconds": round(time.perf_counter() - start, 1),
        }
        fitted[k] = gmm
        log(f"K={k}: {scores[k]}")
    return fitted, scores


def with_hands(gmm) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K, 69) means, (K, 69, 69) covariances, (K,) weights: the body mixture with the hands' Gaussian."""
    k = len(gmm.weights_)
    width = BODY + 6
    means = np.zeros((k, width))
    means[:, :BODY] = gmm.means_
    covars = np.zeros((k, width, width))
    covars[:, :BODY, :BODY] = gmm.covariances_
    covars[:, BODY:, BODY:] = np.eye(6) * HAND_STD**2
    return means, covars, np.asarray(gmm.weights_, np.float64)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mocap", type=Path, default=ROOT.parent / "shared" / "data" / "mocap")
    ap.add_argument("--out", type=Path, default=None, help="default: src/smplcore/data/pose_prior_open.npz "
                    "(with --quick: nothing is written unless --out is given)")  # fmt: skip
    ap.add_argument("--report", type=Path, default=None, help="write the numbers as JSON here")
    ap.add_argument("--poses", type=Path, default=None, help="also save the retargeted poses (.npz) here")
    ap.add_argument("--fps", type=float, default=30.0)
    ap.add_argument("--components", default="1,4,8,16,32")
    ap.add_argument("--gmm-stride", type=int, default=3, help="fit the mixtures on every n-th frame (30 fps / 3 = 10)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--quick", action="store_true", help=f"only {len(QUICK_CLIPS)} clips and K in 1,2")
    ap.add_argument("-q", "--quiet", action="store_true")
    args = ap.parse_args(argv)
    log = (lambda s: None) if args.quiet else (lambda s: print(s, flush=True))
    if not (args.mocap / "index.csv").exists():
        ap.error(f"--mocap: {args.mocap} has no index.csv (the shared mocap folder)")
    ks = [1, 2] if args.quick else [int(k) for k in args.components.split(",")]
    out = args.out if args.out or args.quick else ROOT / "src" / "smplcore" / "data" / "pose_prior_open.npz"
    np.random.seed(args.seed)
    start = time.perf_counter()
    rows = read_index(args.mocap, args.quick)
    clips, _ = retarget_all(args.mocap, rows, args.fps, log)
    retarget_seconds = time.perf_counter() - start
    model = smplcore.BodyModel(model_type="open")
    names = list(model.joint_names[1:24])
    train = [c for c in clips if c["subject"] not in HELD_OUT]
    held = [c for c in clips if c["subject"] in HELD_OUT]
    x_train = np.concatenate([c["fit"].body_pose for c in train])
    x_held = np.concatenate([c["fit"].body_pose for c in held])
    point_errors = np.concatenate([c["fit"].point_error.ravel() for c in clips])
    fitted, scores = fit_mixtures(x_train[:: args.gmm_stride], x_held, ks, args.seed, log)
    best = max(ks, key=lambda k: scores[k]["held_out_loglik"])
    means, covars, weights = with_hands(fitted[best])
    report = {
        "command": "python tools/train_pose_prior.py"
        + (" --quick" if args.quick else "")
        + ("" if args.fps == 30 else f" --fps {args.fps:g}")
        + ("" if args.seed == 0 else f" --seed {args.seed}"),
        "fps": args.fps,
        "clips": len(clips),
        "frames": {"train": len(x_train), "held_out": len(x_held), "gmm_stride": args.gmm_stride},
        "subjects": {"train": sorted({c["subject"] for c in train}), "held_out": sorted({c["subject"] for c in held})},
        "retarget": {
            "joint_error_mean_mm": round(float(point_errors.mean() * 1000), 3),
            "joint_error_p95_mm": round(float(np.percentile(point_errors, 95) * 1000), 3),
            "iterations_mean": round(float(np.mean([c["fit"].iterations for c in clips])), 2),
            "fit_seconds": round(sum(c["fit"].seconds for c in clips), 1),
            "seconds_with_reading": round(retarget_seconds, 1),
            "limits_train": limit_report(x_train, names),
            "limits_held_out": limit_report(x_held, names),
        },
        "mixtures": {str(k): v for k, v in scores.items()},
        "chosen_components": best,
        "loglik_note": "mean log-likelihood per pose of the 63 body values (nats), full mixture density",
        "reg_covar_rad2": REG_COVAR,
        "hand_std_rad": HAND_STD,
        "seconds_total": round(time.perf_counter() - start, 1),
    }
    provenance = (
        LICENCE
        + " "
        + json.dumps(
            {k: report[k] for k in ("command", "fps", "clips", "frames", "subjects", "mixtures", "chosen_components")}
        )
    )
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(out, means=means, covars=covars, weights=weights, provenance=np.array(provenance),
                            joint_names=np.array(names))  # fmt: skip
        report["file"] = str(out)
        report["file_bytes"] = out.stat().st_size
    if args.poses is not None:
        np.savez_compressed(args.poses, **{c["file"].replace("/", "__"): c["fit"].body_pose for c in clips})
    if args.report is not None:
        args.report.write_text(json.dumps(report, indent=1))
    log(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
