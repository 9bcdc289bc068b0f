"""Time to the first body: ``create`` and the first forward of smplcore against smplx, each in a fresh process.

python bench/first_body.py [--rounds 5]   # fake official SMPL (.pkl) and SMPL-X (.npz) files; about a minute

Each measurement runs in its own Python process (imports done before the clock starts: ``import torch`` and the
library), the two libraries alternating, and prints the medians, their ratio and the CPU.
"""

from __future__ import annotations

import argparse
import json
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
t1 = time.perf_counter()
model = lib.create({root!r}, model_type={model_type!r}, ext={ext!r}, num_betas=10)
t2 = time.perf_counter()
with torch.no_grad():
    out = model(betas=torch.zeros(1, 10), body_pose=0.1 * torch.ones(1, {width}), global_orient=torch.zeros(1, 3))
float(out.vertices.sum())
t3 = time.perf_counter()
print(json.dumps({{"import": t1 - t0, "create": t2 - t1, "forward": t3 - t2}}))
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    root = fakes.write_all(tempfile.mkdtemp())["root"]
    print(f"CPU: {_cpu()}; Python {platform.python_version()}; medians of {args.rounds} fresh processes each")
    print(f"{'model':7s} {'library':9s} {'import s':>9s} {'create s':>9s} {'1st fwd s':>9s} {'create+fwd':>10s}")
    for model_type, ext, width in (("smpl", "pkl", 69), ("smplx", "npz", 63)):
        times: dict[str, list[dict[str, float]]] = {"smplcore": [], "smplx": []}
        for _ in range(args.rounds):
            for module in times:
                times[module].append(_run(module, root, model_type, ext, width))
        totals = {}
        for module, runs in times.items():
            med = {k: statistics.median(r[k] for r in runs) for k in ("import", "create", "forward")}
            totals[module] = med["create"] + med["forward"]
            print(
                f"{model_type:7s} {module:9s} {med['import']:9.3f} {med['create']:9.3f} {med['forward']:9.3f} "
                f"{totals[module]:10.3f}"
            )
        print(f"{model_type:7s} smplcore / smplx (create + first forward): {totals['smplcore'] / totals['smplx']:.2f}x")


if __name__ == "__main__":
    main()
