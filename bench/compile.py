"""Eager vs torch.compile (Inductor) forward of smplcore, interleaved in one process (medians of 5 rounds).

python bench/compile.py      # fake official SMPL and SMPL-X files; a few minutes (compilation included)
"""

import statistics
import sys
import time
import warnings

import torch

warnings.filterwarnings("ignore")
sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[1] / "tests"))
import fakes
import smplcore

root = fakes.write_all(__import__("tempfile").mkdtemp())["root"]
for mt, n in (("smpl", 69), ("smplx", 63)):
    m = smplcore.create(root, model_type=mt, num_betas=10, use_pca=False, create_transl=False)
    m.requires_grad_(False)
    c = torch.compile(m)
    for B, grad in ((1, False), (64, False), (512, False), (64, True)):
        x = dict(betas=torch.randn(B, 10), body_pose=torch.randn(B, n) * 0.3, global_orient=torch.randn(B, 3))
        if grad:
            x = {k: v.requires_grad_(True) for k, v in x.items()}

        def run(f):
            if grad:
                o = f(**x)
                (o.vertices.sum() + o.joints.sum()).backward()
            else:
                with torch.no_grad():
                    f(**x)

        for f in (m, c):
            run(f)
            run(f)
        tm = {"eager": [], "compiled": []}
        for r in range(5):
            for name, f in (("eager", m), ("compiled", c)):
                k = 20 if B <= 64 else 3
                t = time.perf_counter()
                for _ in range(k):
                    run(f)
                tm[name].append((time.perf_counter() - t) / k)
        e, cc = statistics.median(tm["eager"]), statistics.median(tm["compiled"])
        print(
            f"{mt} B={B}{' fwd+bwd' if grad else ''}: eager {e * 1e3:.2f} ms, compiled {cc * 1e3:.2f} ms, compiled/eager {cc / e:.2f}",
            flush=True,
        )
