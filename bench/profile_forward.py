"""Where smplcore's torch forward spends its time: per stage and per op.

    python bench/profile_forward.py                      # SMPL and SMPL-X, B=512
    python bench/profile_forward.py --models smplx --batch 64 --ops 25

1. The whole call (``model(**params)`` under ``torch.no_grad()``), median of a few runs.
2. The same pipeline stage by stage, with the engine's own functions on the module's arrays
   (pose to rotation matrices, skeleton, pose features, and the vertex-blocked blend + skinning with
   its GEMM parts timed alone), each timed alone.
3. ``torch.profiler`` by op (self CPU time).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import fixtures  # noqa: E402
import peers  # noqa: E402
import torch  # noqa: E402


def timeit(fn, repeats: int) -> float:
    fn()
    ts = []
    for _ in range(repeats):
        time.sleep(0.02)
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


def stages(model, x: dict, repeats: int) -> tuple[list[tuple[str, float]], list[tuple[str, float]]]:
    """Time each stage of the no-grad forward alone, on the module's own arrays."""
    from smplcore.engine import body as engine
    from smplcore.engine.kernels import blocked
    from smplcore.engine.rotations import pose_features, rodrigues

    arrays = model.source.fast_arrays()
    spec = model.setup.spec
    order = [b.name for b in spec.pose_blocks]
    batch = x["betas"].shape[0]
    coeffs = torch.cat([x["betas"]] + ([x["expression"]] if "expression" in x else []), 1)
    full_pose = torch.cat([x[k] for k in order], 1)
    rotmats = rodrigues(full_pose.reshape(batch, -1, 3))
    _, transforms = engine.pose_skeleton(coeffs, rotmats, arrays.joint_basis, arrays.tree)
    feats = engine.blend_features(coeffs, rotmats, arrays)
    num_verts = arrays.weights_t.shape[1]
    blocks = arrays.vertex_blocks(blocked.block_size(batch, num_verts))
    basis = arrays.blend_basis[: feats.shape[1]]

    def blend_gemms():  # the blend GEMM part of posed_vertices, block by block
        for b in blocks:
            for c in range(3):
                feats @ basis[:, c * num_verts + b.start : c * num_verts + b.stop]

    rows = transforms.permute(1, 0, 2).reshape(transforms.shape[1], -1)

    def weight_gemms():  # the weights @ transforms part, over each block's joints
        for b in blocks:
            (rows if b.joints is None else rows[b.joints]).T @ b.weights_t

    out = []
    with torch.no_grad():
        t = timeit(lambda: torch.cat([x[k] for k in order], 1), repeats)
        out.append(("pose blocks -> (B, 3J) (concat)", t))
        t = timeit(lambda: rodrigues(full_pose.reshape(batch, -1, 3)), repeats)
        out.append(("Rodrigues (axis-angle -> R)", t))
        t = timeit(lambda: engine.pose_skeleton(coeffs, rotmats, arrays.joint_basis, arrays.tree), repeats)
        out.append(("skeleton (joints, chain, transforms)", t))
        if arrays.has_pose_correctives:
            out.append(("pose features (R - I)", timeit(lambda: pose_features(rotmats), repeats)))
        t_all = timeit(lambda: blocked.posed_vertices(feats, transforms, arrays.blend_basis, blocks), repeats)
        t_blend, t_weights = timeit(blend_gemms, repeats), timeit(weight_gemms, repeats)
        out.append((f"blend + skinning ({len(blocks)} vertex blocks)", t_all))
        out.append(("  of which blend GEMMs", t_blend))
        out.append(("  of which weights GEMMs", t_weights))
        out.append(("  of which applying the 3×4 (rest)", t_all - t_blend - t_weights))
    return [r for r in out if not r[0].startswith("  ")], [r for r in out if r[0].startswith("  ")]


def main() -> int:
    warnings.filterwarnings("ignore")
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", default="smpl,smplx")
    ap.add_argument("--batch", type=int, default=512)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--ops", type=int, default=15, help="rows of the torch.profiler table")
    args = ap.parse_args()
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, B={args.batch}")
    for key in args.models.split(","):
        info = peers.model_info(key)
        files = fixtures.prepare(key)
        c = peers.SmplcoreTorch(info, files)
        x = c.prepare(peers.canonical_params(info, args.batch))
        total = timeit(lambda c=c, x=x: c.forward(x), args.repeats)
        print(
            f"\n[{info.label}] B={args.batch}: whole call {total * 1e3:.1f} ms "
            f"({peers.model_info(key).num_verts} vertices, {info.num_joints} joints)"
        )
        print(f"  {'stage':44s} {'ms':>9s} {'% of call':>10s}")
        rows, parts = stages(c.model, x, args.repeats)
        for name, t in rows:
            print(f"  {name:44s} {t * 1e3:9.2f} {100 * t / total:9.0f}%")
            if name.startswith("blend + skinning"):
                for pname, pt in parts:
                    print(f"  {pname:44s} {pt * 1e3:9.2f} {100 * pt / total:9.0f}%")
        print(
            f"  {'sum of stages':44s} {sum(t for _, t in rows) * 1e3:9.2f} "
            f"{100 * sum(t for _, t in rows) / total:9.0f}%"
        )

        from torch.profiler import ProfilerActivity, profile

        with torch.no_grad(), profile(activities=[ProfilerActivity.CPU]) as prof:
            for _ in range(3):
                c.model(**x)
        print(prof.key_averages().table(sort_by="self_cpu_time_total", row_limit=args.ops, max_name_column_width=28))

    return 0


if __name__ == "__main__":
    sys.exit(main())
