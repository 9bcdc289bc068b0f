"""Where smplcore's torch forward spends its time: per stage and per op.

    python bench/profile_forward.py                      # SMPL and SMPL-X, B=512
    python bench/profile_forward.py --models smplx --batch 64 --ops 25

1. The whole call (``model(**params)`` under ``torch.no_grad()``), median of a few runs.
2. The same pipeline stage by stage, with the engine's own functions on the module's arrays
   (pose to rotation matrices, rest joints, kinematic chain, skinning transforms, blend-shape GEMM,
   weights @ transforms, applying the blended 3×4 transforms, keypoint gather), each timed alone.
3. ``torch.profiler`` by op (self CPU time).
4. A prototype of the blend + skinning rewritten in vertex blocks with a planar (B, 3, n) layout (see
   :func:`planar_chunked_forward`): the same numbers, to size the possible gain. It reuses the
   module's arrays and does not touch ``src/``.
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


def stages(model, x: dict, repeats: int) -> list[tuple[str, float]]:
    """Time each stage of the forward alone, on the module's own arrays."""
    from smplcore.engine import body as engine
    from smplcore.engine import skeleton
    from smplcore.engine.rotations import pose_features, rodrigues

    arrays = model._engine_arrays()
    spec = model.setup.spec
    order = [b.name for b in spec.pose_blocks]
    batch = x["betas"].shape[0]
    coeffs = torch.cat([x["betas"]] + ([x["expression"]] if "expression" in x else []), 1)
    full_pose = torch.cat([x[k] for k in order], 1)
    rotmats = rodrigues(full_pose.reshape(batch, -1, 3))
    joints = engine.rest_joints(coeffs, arrays)
    world_rot, world_pos = skeleton.world_transforms(rotmats, joints, arrays.tree)
    transforms = skeleton.skinning_transforms(world_rot, world_pos, joints)
    v = engine.rest_vertices(coeffs, rotmats, arrays)
    weights_t = arrays.weights_t
    num_joints, num_verts = weights_t.shape
    chunk = max(1, getattr(skeleton, "_CHUNK_VALUES", 1 << 20) // (12 * num_verts))
    per_vertex = transforms.mT.reshape(batch * 12, num_joints)

    def skin_gemms():  # the GEMM part of skeleton.skin, chunk by chunk
        for start in range(0, batch, chunk):
            stop = min(start + chunk, batch)
            per_vertex[12 * start : 12 * stop] @ weights_t

    out = []
    with torch.no_grad():
        t = timeit(lambda: torch.cat([x[k] for k in order], 1), repeats)
        out.append(("pose blocks -> (B, 3J) (concat)", t))
        out.append(
            (
                "Rodrigues (axis-angle -> R)",
                timeit(lambda: rodrigues(full_pose.reshape(batch, -1, 3)), repeats),
            )
        )
        out.append(("rest joints (K -> J x 3)", timeit(lambda: engine.rest_joints(coeffs, arrays), repeats)))
        t = timeit(lambda: skeleton.world_transforms(rotmats, joints, arrays.tree), repeats)
        out.append(("kinematic chain (world R, t)", t))
        t = timeit(lambda: skeleton.skinning_transforms(world_rot, world_pos, joints), repeats)
        out.append(("skinning transforms (B, J, 12)", t))
        if arrays.has_pose_correctives:
            out.append(("pose features (R - I)", timeit(lambda: pose_features(rotmats), repeats)))
        t = timeit(lambda: engine.rest_vertices(coeffs, rotmats, arrays), repeats)
        out.append(("blend GEMM [1, K, P] @ basis -> (B, 3, V)", t))
        t_skin = timeit(lambda: skeleton.skin(v, transforms, weights_t), repeats)
        t_gemm = timeit(skin_gemms, repeats)
        out.append((f"LBS (skeleton.skin, {chunk} bodies per chunk)", t_skin))
        out.append(("  of which weights GEMMs (B·12, J) @ (J, V)", t_gemm))
        out.append(("  of which applying the 3×4 (rest = elementwise)", t_skin - t_gemm))
    return [r for r in out if not r[0].startswith("  ")], [r for r in out if r[0].startswith("  ")]


def _vertex_blocks(model, chunk: int) -> list:
    """The blend basis and the weights cut into vertex blocks (each block coordinate-major)."""
    cache = model.__dict__.setdefault("_bench_vertex_blocks", {})
    if chunk not in cache:
        arrays = model._engine_arrays()
        weights_t, basis = arrays.weights_t, arrays.blend_basis
        nv = weights_t.shape[1]
        blocks = []
        for s in range(0, nv, chunk):
            e = min(nv, s + chunk)
            cols = torch.cat([torch.arange(s, e) + k * nv for k in range(3)])
            blocks.append((s, e, basis[:, cols].contiguous(), weights_t[:, s:e].contiguous()))
        cache[chunk] = blocks
    return cache[chunk]


def planar_chunked_forward(model, x: dict, chunk: int = 1024) -> tuple[torch.Tensor, torch.Tensor]:
    """Prototype: the same math with the mesh cut into vertex blocks (the whole batch per block).

    For each block of ``chunk`` vertices:

    * blend GEMM ``[1, coeffs, pose features] (B × R) @ basis block (R × 3n)`` -> (B, 3, n)
      (the basis pre-cut into blocks, so the whole basis is still read once per call, and the
      GEMM keeps M = B rows: full efficiency);
    * ``weights @ transforms`` as one GEMM ``(B·12, J) @ (J, n)`` -> (B, 12, n);
    * the blended 3×4 transforms applied with in-place multiply-adds on contiguous (B, n) rows;
    * written into the (B, V, 3) output: the temporaries (B × 15 × n values, ~30 MB at B=512,
      n=1024) are the same size for every block, so the allocator hands the same memory back,
      and the output is the only large fresh allocation.
    """
    from smplcore.engine import body as engine
    from smplcore.engine.rotations import pose_features, rodrigues
    from smplcore.engine.skeleton import skinning_transforms, world_transforms

    arrays = model._engine_arrays()
    blocks = _vertex_blocks(model, chunk)
    spec = model.setup.spec
    batch = x["betas"].shape[0]
    coeffs = torch.cat([x["betas"]] + ([x["expression"]] if "expression" in x else []), 1)
    full_pose = torch.cat([x[b.name] for b in spec.pose_blocks], 1)
    rotmats = rodrigues(full_pose.reshape(batch, -1, 3))
    joints = engine.rest_joints(coeffs, arrays)
    world_rot, world_pos = world_transforms(rotmats, joints, arrays.tree)
    transforms = skinning_transforms(world_rot, world_pos, joints)  # (B, J, 12): R row-major, then t
    feats = torch.cat([torch.ones_like(coeffs[:, :1]), coeffs], 1)
    if arrays.has_pose_correctives:
        feats = torch.cat([feats, pose_features(rotmats)], 1)
    t_rows = transforms.transpose(1, 2).reshape(batch * 12, -1).contiguous()  # (B·12, J)
    out = torch.empty(batch, arrays.weights_t.shape[1], 3, dtype=transforms.dtype)
    for s, e, basis, w_t in blocks:
        n = e - s
        rest = (feats @ basis[: feats.shape[1]]).view(batch, 3, n)
        blended = (t_rows @ w_t).view(batch, 12, n)
        px, py, pz = rest[:, 0], rest[:, 1], rest[:, 2]
        block = out[:, s:e]
        for c in range(3):
            o = blended[:, 3 * c] * px
            o.addcmul_(blended[:, 3 * c + 1], py).addcmul_(blended[:, 3 * c + 2], pz).add_(blended[:, 9 + c])
            block[:, :, c] = o
    return out, world_pos


def main() -> int:
    warnings.filterwarnings("ignore")
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", default="smpl,smplx")
    ap.add_argument("--batch", type=int, default=512)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--ops", type=int, default=15, help="rows of the torch.profiler table")
    ap.add_argument("--chunk", type=int, default=1024, help="vertex block of the planar prototype")
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
            if name.startswith("LBS"):
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

        with torch.no_grad():
            v_ref, j_ref = c.forward(x)
            v_new, j_new = planar_chunked_forward(c.model, x, args.chunk)
            diff = float((v_new - v_ref).abs().max())
            t_new = timeit(lambda c=c, x=x: planar_chunked_forward(c.model, x, args.chunk), args.repeats)
        print(
            f"  prototype: vertex blocks of {args.chunk}, planar layout: {t_new * 1e3:.1f} ms for the vertices and "
            f"skeleton joints vs {total * 1e3:.1f} ms ({total / t_new:.1f}x); max |Δ| vertices "
            f"{diff:.1e} m"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
