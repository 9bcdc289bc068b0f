"""Motion datasets to joints / vertices: frames per second of ``smplcore process`` vs a smplx loop.

Measures, on synthetic AMASS-style trees (120 fps SMPL+H sequences, no resampling so every source
frame is evaluated):

* ``smplcore process`` (:func:`smplcore.motion.process_tree`) with 1 and 2 worker processes, to
  joints and to vertices, with its default backend (torch on the CPU when installed) and with NumPy;
* the usual way: one process looping over the sequences, calling ``smplx`` on chunks of frames
  (``torch.no_grad``, torch threads = the cores given), saving the joints (or vertices) per file;

for a fake SMPL+H of real size (6890 vertices, 52 joints, 16 betas; ``tests/fakes.py``) and the
packaged open model (13380 vertices, 24 joints; written in the SMPL layout for smplx).

Wall-clock frames/s include everything a user waits for: starting the workers (imports), loading
models, reading inputs and writing outputs. Usage::

    python bench/motion.py              # full run, writes bench/MOTION_RESULTS.md
    python bench/motion.py --quick      # small trees, a quick look
"""

from __future__ import annotations

import argparse
import os
import pickle
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))


def write_models(root: Path) -> dict[str, dict]:
    """Model files: smplcore reads them from ``folder``; smplx from ``smplx_root`` / ``smplx_type``."""
    import fakes
    from smplcore.io.locate import OPEN_MODEL_PATH

    models = {}
    path = fakes.write_smplh(root / "smplh", "female", "npz", amass=True, hand_pca=True)
    models["SMPL+H (fake, real size)"] = {
        "folder": path,
        "smplx_root": root,
        "smplx_type": "smplh",
        "ext": "npz",
        "model_type": None,
    }
    if OPEN_MODEL_PATH.exists():
        d = np.load(OPEN_MODEL_PATH, allow_pickle=False)
        v = np.asarray(d["v_template"], np.float64)
        parents = np.asarray(d["parents"], np.int64)
        kintree = np.stack([np.where(parents < 0, 4294967295, parents), np.arange(len(parents))]).astype(np.int64)
        arrays = {
            "v_template": v,
            "f": np.asarray(d["faces"], np.uint32),
            "shapedirs": np.asarray(d["shapedirs"], np.float64),
            "posedirs": np.zeros((v.shape[0], 3, 9 * (len(parents) - 1))),
            "J_regressor": np.asarray(d["J_regressor"], np.float64),
            "weights": np.asarray(d["weights"], np.float64),
            "kintree_table": kintree,
        }
        (root / "open_smpl" / "smpl").mkdir(parents=True, exist_ok=True)
        with open(root / "open_smpl" / "smpl" / "SMPL_NEUTRAL.pkl", "wb") as fh:
            pickle.dump(arrays, fh, protocol=4)
        models["open model"] = {
            "folder": None,
            "smplx_root": root / "open_smpl",
            "smplx_type": "smpl",
            "ext": "pkl",
            "model_type": "open",
        }
    else:
        print(f"note: {OPEN_MODEL_PATH} is absent: the open model is left out", file=sys.stderr)
    return models


def write_inputs(root: Path, count: int, frames: int) -> Path:
    from smplcore.motion.synthetic import write_tree

    write_tree(root, [(f"S{i % 4}/seq{i:03d}_poses.npz", frames, 120.0, "female") for i in range(count)], seed=1)
    return root


def run_smplcore(tree: Path, out: Path, model: dict, *, workers: int, vertices: bool, backend: str) -> dict:
    from smplcore.motion import ProcessOptions, process_tree

    shutil.rmtree(out, ignore_errors=True)
    options = ProcessOptions(
        model_path=None if model["folder"] is None else str(model["folder"]),
        model_type=model["model_type"],
        vertices=vertices,
        backend=backend,
    )
    summary = process_tree(tree, out, options, workers=workers, progress=False)
    assert summary.exit_code == 0, summary.format()
    import json

    entries = json.loads((out / "manifest.json").read_text())["files"]
    busy = sum(e["seconds"] for e in entries) / workers
    shutil.rmtree(out, ignore_errors=True)
    return {
        "frames": summary.frames,
        "seconds": summary.seconds,
        "fps": summary.frames_per_second,
        "busy_fps": summary.frames / busy if busy else 0.0,
    }


def run_smplx_loop(tree: Path, out: Path, model: dict, *, threads: int, vertices: bool, chunk: int) -> dict:
    """The usual way: for each sequence, smplx on chunks of frames, joints (or vertices) saved per file."""
    import smplx
    import torch

    torch.set_num_threads(threads)
    shutil.rmtree(out, ignore_errors=True)
    start = time.perf_counter()
    kwargs = {
        "model_type": model["smplx_type"],
        "ext": model["ext"],
        "gender": "female" if model["smplx_type"] == "smplh" else "neutral",
        "num_betas": 16 if model["smplx_type"] == "smplh" else 10,
    }
    if model["smplx_type"] == "smplh":
        kwargs.update(use_pca=False, flat_hand_mean=True)
    body = smplx.create(str(model["smplx_root"]), **kwargs)
    frames = 0
    for path in sorted(tree.rglob("*.npz")):
        data = np.load(path)
        poses = torch.as_tensor(data["poses"], dtype=torch.float32)
        trans = torch.as_tensor(data["trans"], dtype=torch.float32)
        betas = torch.as_tensor(data["betas"][: body.num_betas], dtype=torch.float32)[None]  # smplx caps SMPL+H at 10
        parts = []
        with torch.no_grad():
            for s in range(0, len(poses), chunk):
                p = poses[s : s + chunk]
                n = len(p)
                args = {
                    "global_orient": p[:, :3],
                    "transl": trans[s : s + chunk],
                    "betas": betas.expand(n, -1),
                }
                if model["smplx_type"] == "smplh":
                    args.update(body_pose=p[:, 3:66], left_hand_pose=p[:, 66:111], right_hand_pose=p[:, 111:156])
                else:
                    args["body_pose"] = torch.cat([p[:, 3:66], torch.zeros(n, 6)], dim=1)
                res = body(**args)
                parts.append((res.vertices if vertices else res.joints[:, : body.NUM_JOINTS + 1]).numpy())
        rel = path.relative_to(tree)
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        np.save(out / rel.with_suffix(".npy"), np.concatenate(parts))
        frames += len(poses)
    seconds = time.perf_counter() - start
    shutil.rmtree(out, ignore_errors=True)
    return {"frames": frames, "seconds": seconds, "fps": frames / seconds, "busy_fps": frames / seconds}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="small trees")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--output", type=Path, default=REPO / "bench" / "MOTION_RESULTS.md")
    parser.add_argument("--no-smplx", action="store_true", help="skip the smplx baseline")
    parser.add_argument("--repeat", type=int, default=2, help="runs of each case; the fastest is kept")
    parser.add_argument("--outputs", nargs="+", choices=("joints", "vertices"), default=["joints", "vertices"])
    parser.add_argument(
        "--backends",
        nargs="+",
        choices=("numpy", "torch"),
        default=None,
        help="smplcore backends to time (default: numpy, and torch when installed)",
    )
    args = parser.parse_args(argv)

    joint_seqs, joint_frames = (8, 2000) if args.quick else (24, 6000)
    vert_seqs, vert_frames = (4, 120) if args.quick else (8, 300)
    load_before = _load_average()
    tmp = Path(tempfile.mkdtemp(prefix="smplcore-bench-motion-"))
    rows = []
    try:
        models = write_models(tmp / "models")
        trees = {
            False: write_inputs(tmp / "joints_in", joint_seqs, joint_frames),
            True: write_inputs(tmp / "verts_in", vert_seqs, vert_frames),
        }
        from smplcore.motion.models import torch_available

        backends = args.backends or (["numpy", "torch"] if torch_available() else ["numpy"])
        for name, model in models.items():
            for vertices in [v for v in (False, True) if ("vertices" if v else "joints") in args.outputs]:
                what = "vertices" if vertices else "joints"
                for backend in backends:
                    for workers in args.workers:
                        r = max(
                            (
                                run_smplcore(
                                    trees[vertices],
                                    tmp / "out",
                                    model,
                                    workers=workers,
                                    vertices=vertices,
                                    backend=backend,
                                )
                                for _ in range(args.repeat)
                            ),
                            key=lambda r: r["fps"],
                        )
                        rows.append((name, what, f"smplcore process ({backend})", workers, r))
                        print(
                            f"{name:26s} {what:8s} smplcore/{backend:5s} {workers} worker(s): "
                            f"{r['fps']:10,.0f} frames/s wall, {r['busy_fps']:10,.0f} while busy",
                            flush=True,
                        )
                if args.no_smplx:
                    continue
                for threads in args.workers:
                    chunk = 1024 if not vertices else 128
                    # smplx builds the whole mesh for joints too: the small tree is enough to time it.
                    r = max(
                        (
                            run_smplx_loop(
                                trees[True],
                                tmp / "out",
                                model,
                                threads=threads,
                                vertices=vertices,
                                chunk=chunk,
                            )
                            for _ in range(args.repeat)
                        ),
                        key=lambda r: r["fps"],
                    )
                    rows.append((name, what, f"smplx loop, chunks of {chunk} (torch threads = cores)", threads, r))
                    print(
                        f"{name:26s} {what:8s} smplx loop  {threads} core(s): {r['fps']:10,.0f} frames/s",
                        flush=True,
                    )
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    lines = [
        "# Motion datasets: frames per second to joints and to vertices",
        "",
        f"`python bench/motion.py{' --quick' if args.quick else ''}` on {platform.machine()} with "
        f"{os.cpu_count()} CPUs, Python {platform.python_version()}, "
        f"NumPy {np.__version__}" + _torch_version() + f"; load average {load_before} before the run, "
        f"{_load_average()} after (other processes share these CPUs: expect run-to-run spread).",
        "",
        "Inputs: synthetic AMASS-style SMPL+H sequences at 120 fps, every frame evaluated (no resampling): "
        f"{joint_seqs} x {joint_frames} frames for joints, {vert_seqs} x {vert_frames} for vertices and for "
        "the smplx loop (which builds the whole mesh either way). "
        "Wall frames/s count everything from the call to the last output (worker start-up and imports, "
        'model loading, reading, evaluating, writing float32 outputs); "busy" divides by the time the '
        f"workers spent on files only. Best of {args.repeat} runs each. Each smplcore worker uses one "
        "core (one BLAS thread). The smplx loop is the usual script: one process, `smplx.create(...)`, "
        "then per sequence `model(...)` under `torch.no_grad()` on chunks of frames, with torch using as "
        "many threads as cores.",
        "",
        "| model | output | how | workers / cores | frames | seconds | frames/s (wall) | frames/s (busy) |",
        "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for name, what, how, n, r in rows:
        lines.append(
            f"| {name} | {what} | {how} | {n} | {r['frames']:,} | {r['seconds']:.2f} | {r['fps']:,.0f} | "
            f"{r['busy_fps']:,.0f} |"
        )
    text = "\n".join(lines) + "\n"
    args.output.write_text(text)
    print(f"\nwrote {args.output}")
    return 0


def _load_average() -> str:
    try:
        return f"{os.getloadavg()[0]:.1f}"
    except (AttributeError, OSError):
        return "n/a"


def _torch_version() -> str:
    try:
        import torch
    except ImportError:
        return ""
    return f", torch {torch.__version__}"


if __name__ == "__main__":
    sys.exit(main())
