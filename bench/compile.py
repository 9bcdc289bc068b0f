"""Eager vs ``torch.compile`` (Inductor) forward of smplcore, interleaved in one process (medians of 5 rounds).

python bench/compile.py      # fake official SMPL and SMPL-X files; a few minutes (compilation included)
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import fakes  # noqa: E402
import smplcore  # noqa: E402


def _call(model, params, grad, **options):
    if grad:
        out = model(**params, **options)
        (out.vertices.sum() + out.joints.sum()).backward()
    else:
        with torch.no_grad():
            model(**params, **options)


def main() -> None:
    warnings.filterwarnings("ignore")
    root = fakes.write_all(tempfile.mkdtemp())["root"]
    # SMPL-X's output has v_shaped: eager computes it only when read (a deferred output), a compiled graph
    # always; the "v_shaped off" rows pass return_shaped=False to both
    cases = (("smpl", 69, {}), ("smplx", 63, {}), ("smplx", 63, {"return_shaped": False}))
    for model_type, width, options in cases:
        torch._dynamo.reset()  # each case compiles afresh (recompilations of one class's forward add up)
        eager = smplcore.create(root, model_type=model_type, num_betas=10, use_pca=False, create_transl=False)
        eager.requires_grad_(False)
        compiled = torch.compile(eager)
        for batch, grad in ((1, False), (64, False), (512, False), (64, True)):
            params = {
                "betas": torch.randn(batch, 10),
                "body_pose": 0.3 * torch.randn(batch, width),
                "global_orient": torch.randn(batch, 3),
            }
            params = {k: v.requires_grad_(grad) for k, v in params.items()}
            for model in (eager, compiled):  # warm-up (compilation)
                _call(model, params, grad, **options)
                _call(model, params, grad, **options)
            times: dict[str, list[float]] = {"eager": [], "compiled": []}
            calls = 20 if batch <= 64 else 3
            for _ in range(5):
                for name, model in (("eager", eager), ("compiled", compiled)):
                    t0 = time.perf_counter()
                    for _ in range(calls):
                        _call(model, params, grad, **options)
                    times[name].append((time.perf_counter() - t0) / calls)
            e, c = statistics.median(times["eager"]), statistics.median(times["compiled"])
            mode = (" fwd+bwd" if grad else "") + (" (v_shaped off)" if options else "")
            print(
                f"{model_type} B={batch}{mode}: eager {e * 1e3:.2f} ms, compiled {c * 1e3:.2f} ms, "
                f"compiled/eager {c / e:.2f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
