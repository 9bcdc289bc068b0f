"""Timing of smplcore.measure: all measurements of one body, and fit_shape on ANSUR II-like targets.

Run: ``PYTHONPATH=src python bench/measure.py [--bodies 50]``. Prints the CPU, seconds per call and the
share of fits that reach stature within 5 mm and waist within 1 cm (targets as in tests/test_measure_fit.py).
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

import smplcore
from smplcore.measure import MEASUREMENTS, fit_shape, measure

ANSUR_II_MEN = {"stature": (1.756, 0.069), "mass": (85.5, 14.2), "waist": (0.941, 0.112)}
CORRELATION = np.array([[1.0, 0.45, 0.20], [0.45, 1.0, 0.85], [0.20, 0.85, 1.0]])


def _cpu() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--bodies", type=int, default=50)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--num-betas", type=int, default=16, help="shape coefficients of the open model (10..16)")
    args = parser.parse_args()
    print(f"CPU: {_cpu()}")
    model = smplcore.BodyModel(model_type="open", gender="male", dtype=np.float64, num_betas=args.num_betas)
    measure(model)
    times = []
    for _ in range(args.repeat):
        t = time.perf_counter()
        measure(model)
        times.append(time.perf_counter() - t)
    print(f"measure (all {len(MEASUREMENTS)}), one body: median {np.median(times) * 1e3:.0f} ms")
    for names in (["stature"], ["stature", "mass", "waist"]):
        t = time.perf_counter()
        measure(model, names=names)
        print(f"measure {names}: {(time.perf_counter() - t) * 1e3:.0f} ms")
    rng = np.random.default_rng(7)
    z = rng.multivariate_normal(np.zeros(3), CORRELATION, size=args.bodies)
    targets = {n: mu + sd * z[:, i] for i, (n, (mu, sd)) in enumerate(ANSUR_II_MEN.items())}
    t = time.perf_counter()
    fit = fit_shape(model, **targets)
    dt = time.perf_counter() - t
    ok = (np.abs(fit.residual["stature"]) <= 0.005) & (np.abs(fit.residual["waist"]) <= 0.01)
    print(
        f"fit_shape stature+mass+waist, {args.bodies} bodies, {args.num_betas} betas: "
        f"{dt / args.bodies * 1e3:.0f} ms per body, "
        f"{np.mean(fit.iterations):.1f} iterations; reached {ok.mean() * 100:.0f} % "
        f"(|mass residual| median {np.median(np.abs(fit.residual['mass'])):.2f} kg, "
        f"max {np.max(np.abs(fit.residual['mass'])):.2f} kg)"
    )


if __name__ == "__main__":
    main()
