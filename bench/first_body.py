"""Time to the first body: ``create`` and the first forward of smplcore against smplx, each in a fresh process.

python bench/first_body.py [--rounds 5] [--models DIR]   # fake official SMPL (.pkl) and SMPL-X (.npz) files

Each measurement runs in its own Python process (imports done before the clock starts: ``import torch``, the
library and, for smplcore, its torch front end, which ``import smplcore`` defers to the first use of
``smplcore.create``), the two libraries alternating, and prints the medians, their ratio and the CPU. Besides the
wall-clock times it prints the ratio of the processes' CPU times (``time.process_time``, all threads) over create and
the first forward, which a loaded machine disturbs less; the load average is printed before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import fakes  # noqa: E402

_CHILD = r"""
import json, sys, time, warnings
warnings.filterwarnings("ignore")
t0 = time.perf_counter()
import torch
import {module} as lib
create = lib.create  # smplcore imports its torch front end here, on first use
t1, c1 = time.perf_counter(), time.process_time()
model = create({root!r}, model_type={model_type!r}, ext={ext!r}, num_betas=10)
t2 = time.perf_counter()
with torch.no_grad():
    out = model(betas=torch.zeros(1, 10), body_pose=0.1 * torch.ones(1, {width}), global_orient=torch.zeros(1, 3))
float(out.vertices.sum())
t3, c3 = time.perf_counter(), time.process_time()
print(json.dumps({{"import": t1 - t0, "create": t2 - t1, "forward": t3 - t2, "cpu": c3 - c1}}))
"""


def _run(module: str, root: Path, model_type: str, ext: str, width: int) -> dict[str, float]:
    code = _CHILD.format(module=module, root=str(root), model_type=model_type, ext=ext, width=width)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def _cpu() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                name = line.split(":", 1)[1].strip()
                flags = Path("/proc/cpuinfo").read_text()
                simd = "AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else "no AVX2"
                return f"{name} ({simd})"
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _load() -> str:
    try:
        return " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:
        return "unknown"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument(
        "--models",
        type=Path,
        help="a folder of fake files written before (fakes.write_all), to reuse; default: new ones",
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        root = args.models or fakes.write_all(scratch)["root"]
        if hasattr(os, "sync"):
            os.sync()  # the fresh files' write-back is done before the clocks run (it would slow the first reads)
        _measure(root, args.rounds)


def _measure(root: Path, rounds: int) -> None:
    print(f"CPU: {_cpu()}; Python {platform.python_version()}; medians of {rounds} fresh processes each")
    print(f"load average before: {_load()}")
    print(f"{'model':7s} {'library':9s} {'import s':>9s} {'create s':>9s} {'1st fwd s':>9s} {'create+fwd':>10s}")
    for model_type, ext, width in (("smpl", "pkl", 69), ("smplx", "npz", 63)):
        times: dict[str, list[dict[str, float]]] = {"smplcore": [], "smplx": []}
        for _ in range(rounds):
            for module in times:
                times[module].append(_run(module, root, model_type, ext, width))
        totals, cpu = {}, {}
        for module, runs in times.items():
            cpu[module] = statistics.median(r["cpu"] for r in runs)
            med = {k: statistics.median(r[k] for r in runs) for k in ("import", "create", "forward")}
            totals[module] = med["create"] + med["forward"]
            print(
                f"{model_type:7s} {module:9s} {med['import']:9.3f} {med['create']:9.3f} {med['forward']:9.3f} "
                f"{totals[module]:10.3f}"
            )
        print(
            f"{model_type:7s} smplcore / smplx (create + first forward): {totals['smplcore'] / totals['smplx']:.2f}x "
            f"wall, {cpu['smplcore'] / cpu['smplx']:.2f}x CPU time ({cpu['smplcore']:.3f} / {cpu['smplx']:.3f} s)"
        )
    print(f"load average after: {_load()}")


if __name__ == "__main__":
    main()
