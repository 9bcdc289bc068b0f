"""Forward-pass benchmark: smplcore (torch, NumPy) against smplx 0.1.28, body-models and smplfitter.

One run, float32, CPU, on fake official files of real size (``tests/fakes.py``: SMPL 6890 vertices,
SMPL+H, SMPL-X 10475 vertices) and on smplcore's open model:

* forward (vertices + joints) at B = 1, 64, 512, without autograd and as forward + backward;
* a joints-only call at B = 4096 (smplx has none, so its full forward is the reference);
* median time, bodies/s, the speed-up over smplx, peak memory (RSS high-water mark of one call, in
  a fresh subprocess per contender), and the share of the machine's float32 GEMM ceiling, from the
  forward's FLOP count and a GEMM of the same size timed in the same group;
* contenders are interleaved (their order rotating each round) and every group is repeated, with an
  idle gap before each sample, so that ratios hold on a noisy, shared 2-core machine.

Usage::

    python bench/forward.py             # full run (< 15 min), writes bench/RESULTS.md
    python bench/forward.py --quick     # a few repeats, fewer sizes (< 2 min); no file unless --output
    python bench/forward.py --models smpl,smplx --contenders smplcore-torch,smplx --modes fwd

See ``--help`` for the options and ``bench/README.md`` for the method.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import datetime as _dt
import gc
import json
import math
import os
import platform
import re
import statistics
import subprocess
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import fixtures  # noqa: E402
import numpy as np  # noqa: E402
import peers  # noqa: E402

ALL_MODELS = ["smpl", "smplh", "smplx", "open"]
ALL_MODES = ["fwd", "fwdbwd", "joints"]
MODE_LABEL = {"fwd": "forward (no grad)", "fwdbwd": "forward + backward", "joints": "joints only"}
TARGET_MODELS = ["smpl", "smplx"]
PEERS = ["body-models-numpy", "body-models-torch", "smplfitter-numpy", "smplfitter-torch"]


# ------------------------------------------------------------------------------------------------
# FLOPs and the GEMM ceiling


def forward_flops(info: peers.ModelInfo) -> float:
    """Dominant floating-point operations of one body's forward (dense LBS), multiply-add = 2.

    ``2·3V·(K + P)`` shape and pose blend shapes (one GEMM), ``2·12·V·J`` blending the J (3×4)
    transforms per vertex with dense weights, ``24·V`` applying them (3×3 matrix-vector product
    and translation: 18) and adding the template and the two offsets (6). Joint regression from
    precomputed joint bases (``2·3J·K``), Rodrigues and the kinematic chain (~100·J) are below 1%.
    """
    v, j, k, p = info.num_verts, info.num_joints, info.num_coeffs, info.num_pose_features
    return 2.0 * 3 * v * (k + p) + 2.0 * 12 * v * j + 24.0 * v


FLOP_FORMULA = "F = 2·3V·(K+P) + 2·12·V·J + 24·V"


def gemm_shape(info: peers.ModelInfo, batch: int) -> tuple[int, int, int]:
    """(M, K, N) of the GEMM the ceiling is measured on: the blend-shape GEMM of this model.

    (B × (K+P)) @ ((K+P) × 3V); for a model without pose correctives (the open model), the SMPL-sized
    inner dimension 217 on this model's 3V columns.
    """
    inner = info.num_coeffs + info.num_pose_features
    if inner < 64:
        inner = 217
    return batch, inner, 3 * info.num_verts


class Gemm:
    """The machine's ceiling: a float32 GEMM of the forward's size. ``torch`` and ``numpy`` allocate the
    output as a forward does; ``torch-out`` writes into one preallocated output (no page faults);
    ``onednn`` runs oneDNN on a B packed once (what smplcore does with its bases, where torch has
    oneDNN): the fastest of them is the GEMM as fast as this machine runs it."""

    grad = False

    def __init__(self, kind: str, shape: tuple[int, int, int]) -> None:
        self.kind, self.shape = kind, shape
        self.name = f"gemm-{kind}"
        m, k, n = shape
        rng = np.random.default_rng(1)
        a, b = rng.standard_normal((m, k), dtype=np.float32), rng.standard_normal((k, n), dtype=np.float32)
        self.out = self.packed = None
        if kind == "onednn":
            import torch

            from smplcore.engine.kernels import gemm

            self.a, self.packed = torch.from_numpy(a), gemm.pack(torch.from_numpy(b))
        elif kind.startswith("torch"):
            import torch

            self.a, self.b = torch.from_numpy(a), torch.from_numpy(b)
            if kind == "torch-out":
                self.out = torch.empty(m, n)
        else:
            self.a, self.b = a, b

    @property
    def flops(self) -> float:
        m, k, n = self.shape
        return 2.0 * m * k * n

    @staticmethod
    def kinds() -> tuple[str, ...]:
        """The kinds this machine has (``onednn`` only where smplcore packs for oneDNN)."""
        import torch

        from smplcore.engine.kernels import gemm

        return ("torch", "torch-out", "numpy") + (("onednn",) if gemm.available(torch.zeros(1)) else ())

    def run(self) -> Any:
        if self.packed is not None:
            from smplcore.engine.kernels import gemm

            return gemm.product(self.a, self.packed)
        if self.out is not None:
            import torch

            return torch.mm(self.a, self.b, out=self.out)
        return self.a @ self.b


# ------------------------------------------------------------------------------------------------
# Timing


@dataclass
class Entry:
    """One contender in one group."""

    name: str
    kind: str  # torch | numpy
    call: Callable[[], Any]
    batch: int
    label: str = ""
    n: int = 1  # calls per sample
    max_samples: int = 0
    samples: list[float] = field(default_factory=list)  # seconds per call, one per round
    error: str | None = None
    skipped: str | None = None  # too slow to repeat: why, and the estimate
    flops: float = 0.0  # GEMM entries
    once: bool = False  # too slow to repeat: one (warm-up) call only

    @property
    def median(self) -> float:
        return statistics.median(self.samples) if self.samples else float("nan")

    @property
    def shown(self) -> str:
        return self.label or self.name


@dataclass
class Group:
    model: str
    mode: str
    batch: int
    entries: list[Entry]
    gemm: dict[str, Entry] = field(default_factory=dict)


@dataclass
class Budget:
    rounds: int
    sample_time: float  # seconds of back-to-back calls per sample
    gap: float  # idle seconds before a torch sample that follows NumPy code
    entry_time: float  # rough seconds of samples per entry and group (slow entries get fewer rounds)
    max_call: float  # peers slower than this per call are timed once, not repeated
    min_samples: int = 2
    reduced: str = ""  # set when a slow spell made the run cut rounds


MUST_RUN = {"smplcore-torch", "smplcore-numpy", "smplx"}


def _idle(prev_kind: str | None, kind: str, gap: float) -> None:
    """Let OpenBLAS worker threads stop spinning before torch code runs."""
    gc.collect()
    # NumPy's OpenBLAS threads spin ~0.1 s after a call and slow the torch code that runs next (up to
    # 3x); torch's OpenMP threads stop spinning within a millisecond.
    if prev_kind is None or (prev_kind == "numpy" and kind != "numpy"):
        time.sleep(gap)
    else:
        time.sleep(0.01)


def _time_calls(fn: Callable[[], Any], n: int) -> float:
    t0 = time.perf_counter()
    for _ in range(n):
        out = fn()
    peers.sync()
    dt = time.perf_counter() - t0
    del out
    return dt / n


def run_group(group: Group, budget: Budget, estimates: dict[str, float], log: Callable[[str], None]) -> None:
    """Warm up and calibrate every entry, then ``budget.rounds`` interleaved rounds.

    ``estimates``: expected seconds per call of some entries (from smaller groups); a peer expected
    to take longer than ``budget.max_call`` is not run at all, one that turns out so is timed once.
    """
    entries = group.entries + list(group.gemm.values())
    prev = None
    for e in entries:
        est = estimates.get(e.name)
        if e.name not in MUST_RUN and est is not None and est > 1.5 * budget.max_call:
            e.skipped = f"not run: ~{est:.0f} s per call expected"
            log(f"    - {e.shown}: {e.skipped}")
            continue
        try:
            _idle(prev, e.kind, budget.gap)
            t0 = time.perf_counter()
            e.call()  # warm-up: allocations, kernel choice
            t = time.perf_counter() - t0
            prev = e.kind
            if t < budget.sample_time:  # calls per sample from the best of a few (this machine is noisy)
                _idle(prev, e.kind, budget.gap)
                t = min(_time_calls(e.call, 1) for _ in range(3))
            elif e.name not in MUST_RUN and t > budget.max_call:
                e.samples, e.n, e.max_samples = [t], 1, 1
                e.skipped = "timed once (one warm-up call)"
                log(f"    - {e.shown}: {t:.1f} s for one call; not repeated")
                continue
        except Exception as exc:  # a library that cannot run this configuration
            e.error = f"{type(exc).__name__}: {exc}"[:300]
            log(f"    ! {e.shown}: {e.error}")
            continue
        e.n = max(1, min(2000, int(math.ceil(budget.sample_time / max(t, 1e-7)))))
        e.max_samples = max(budget.min_samples, min(budget.rounds, int(budget.entry_time / max(t * e.n, 1e-9))))
    live = [e for e in entries if e.error is None and e.skipped is None]
    for e in entries:
        if e.skipped and e.samples:  # timed once: keep the sample, run no more
            e.skipped = None
            e.once = True
    kinds = {"torch": [e for e in live if e.kind == "torch"], "numpy": [e for e in live if e.kind == "numpy"]}
    for r in range(budget.rounds):
        # Rotate the order within each kind; alternate which kind goes first (few NumPy -> torch switches).
        order = []
        for kind in ("torch", "numpy") if r % 2 == 0 else ("numpy", "torch"):
            lst = kinds[kind]
            k = (r // 2) % max(1, len(lst))
            order += lst[k:] + lst[:k]
        for e in order:
            if len(e.samples) >= e.max_samples:
                continue
            _idle(prev, e.kind, budget.gap)
            e.samples.append(_time_calls(e.call, e.n))
            prev = e.kind


def ratio_to(group: Group | None, name: str, ref: str = "smplx") -> float:
    """Speed-up of ``name`` over ``ref`` in bodies/s: median over rounds of the per-round ratio."""
    if group is None:
        return float("nan")
    a = next((e for e in group.entries if e.name == name and e.samples), None)
    b = next((e for e in group.entries if e.name == ref and e.samples), None)
    if a is None or b is None:
        return float("nan")
    return statistics.median([(tb / b.batch) / (ta / a.batch) for ta, tb in zip(a.samples, b.samples, strict=False)])


def ceiling(group: Group) -> float:
    """The machine's float32 GEMM ceiling in this group: the fastest of the GEMMs (GFLOP/s)."""
    rates = [gemm_gflops(group, kind) for kind in group.gemm]
    rates = [r for r in rates if math.isfinite(r)]
    return max(rates) if rates else float("nan")


def gemm_gflops(group: Group, kind: str) -> float:
    e = group.gemm.get(kind)
    if e is None or not e.samples:
        return float("nan")
    return e.flops / e.median / 1e9


# ------------------------------------------------------------------------------------------------
# Peak memory, one fresh subprocess per measurement


def _status_kib(key: str) -> int:
    with open("/proc/self/status") as fh:
        m = re.search(rf"^{key}:\s+(\d+)", fh.read(), re.M)
    return int(m.group(1)) if m else -1


def _bound(c: peers.Contender, mode: str, x: Any) -> Callable[[], Any]:
    method = {"fwd": c.forward, "joints": c.joints, "fwdbwd": c.fwd_bwd}[mode]
    return lambda: method(x)


def memory_probe(model: str, jobs: list[tuple[str, str, int]], cache: str | None) -> dict:
    """Run in a fresh process: for each (contender, mode, batch), the RSS high-water mark of one call
    above the RSS just before it (MiB).

    The process starts with glibc's mmap threshold fixed (see :func:`measure_memory`), so blocks freed
    by one measurement go back to the kernel and do not hide the next one's; before each call the
    kernel's high-water mark is reset to the current RSS (``/proc/self/clear_refs``).
    """
    warnings.filterwarnings("ignore")
    import ctypes

    try:
        trim = ctypes.CDLL("libc.so.6").malloc_trim
    except OSError:
        trim = None
    files = fixtures.prepare(model, cache)
    info = peers.model_info(model)
    results = {}
    for contender, mode, batch in jobs:
        key = f"{contender}/{mode}/{batch}"
        try:
            c = peers.CONTENDERS[contender](info, files)
            params = peers.canonical_params(info, batch)
            x = c.prepare(params, grad=mode == "fwdbwd")
            fn = _bound(c, mode, x)
            peaks = []
            for _ in range(2):  # the first call may set up lazily; the second is the steady state
                gc.collect()
                if trim is not None:
                    trim(0)
                base = _status_kib("VmRSS")
                with open("/proc/self/clear_refs", "w") as fh:  # reset VmHWM to the current RSS
                    fh.write("5")
                t0 = time.perf_counter()
                out = fn()
                peaks.append((_status_kib("VmHWM") - base, base))
                del out
                if time.perf_counter() - t0 > 2.0:  # slow: one call is enough
                    break
            peak, base = peaks[-1]
            del x, c, fn
            results[key] = {"peak_mib": peak / 1024.0, "base_mib": base / 1024.0, "calls": len(peaks)}
        except Exception as exc:
            results[key] = {"error": f"{type(exc).__name__}: {exc}"[:200]}
        gc.collect()
        if trim is not None:
            trim(0)
    return results


def measure_memory(
    jobs: list[tuple[str, str, str, int]], cache: str | None, log: Callable[[str], None], parallel: int = 2
) -> dict[tuple, dict]:
    """Peak memory of one call per (model, contender, mode, batch): one fresh process per model."""
    env = dict(os.environ)
    # Large blocks from mmap and given back on free, so RSS follows what a call really holds.
    env.update(MALLOC_MMAP_THRESHOLD_="131072", MALLOC_TRIM_THRESHOLD_="131072", PYTHONWARNINGS="ignore")
    by_model: dict[str, list] = {}
    for model, contender, mode, batch in jobs:
        by_model.setdefault(model, []).append((contender, mode, batch))

    def one(model):
        spec = ";".join(f"{c},{m},{b}" for c, m, b in by_model[model])
        cmd = [sys.executable, str(Path(__file__).resolve()), "--memory-probe", model, spec]
        if cache:
            cmd += ["--cache", cache]
        try:
            p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=900)
        except subprocess.TimeoutExpired:
            return model, {f"{c}/{m}/{b}": {"error": "timeout"} for c, m, b in by_model[model]}
        lines = [ln for ln in p.stdout.splitlines() if ln.startswith("{")]
        if p.returncode != 0 or not lines:
            err = (p.stderr.strip().splitlines() or ["?"])[-1][:200]
            return model, {f"{c}/{m}/{b}": {"error": err} for c, m, b in by_model[model]}
        return model, json.loads(lines[-1])

    results = {}
    with concurrent.futures.ThreadPoolExecutor(parallel) as pool:
        order = sorted(by_model, key=lambda m: ["smplx", "open", "smplh", "smpl"].index(m))  # longest first
        for model, res in pool.map(one, order):
            for contender, mode, batch in by_model[model]:
                r = res.get(f"{contender}/{mode}/{batch}", {"error": "missing"})
                results[(model, contender, mode, batch)] = r
                val = f"{r['peak_mib']:8.1f} MiB" if "peak_mib" in r else f"error: {r['error']}"
                log(f"    memory {model:6s} {mode:6s} B={batch:<5d} {contender:18s} {val}")
    return results


# ------------------------------------------------------------------------------------------------
# Reporting helpers


def fmt_time(s: float) -> str:
    if not math.isfinite(s):
        return "—"
    if s < 1e-3:
        return f"{s * 1e6:.0f} µs"
    if s < 1:
        return f"{s * 1e3:.2f} ms"
    return f"{s:.2f} s"


def fmt_num(x: float, digits: int = 1, suffix: str = "") -> str:
    if x is None or not math.isfinite(x):
        return "—"
    return f"{x:,.{digits}f}{suffix}"


def fmt_rate(x: float) -> str:
    if not math.isfinite(x):
        return "—"
    return f"{x:,.0f}" if x >= 100 else f"{x:,.1f}"


def machine_info() -> dict[str, str]:
    import torch

    cpu = platform.processor() or "?"
    try:
        with open("/proc/cpuinfo") as fh:
            txt = fh.read()
        m = re.search(r"model name\s*:\s*(.+)", txt)
        cpu = m.group(1).strip() if m else cpu
        flags = set(re.search(r"flags\s*:\s*(.+)", txt).group(1).split())
        isa = ", ".join(f for f in ("avx2", "fma", "avx512f", "avx512_vnni", "avx512_bf16", "amx_tile") if f in flags)
    except (OSError, AttributeError):
        isa = "?"
    try:
        with open("/proc/meminfo") as fh:
            mem = int(re.search(r"MemTotal:\s+(\d+)", fh.read()).group(1)) / 1024**2
        mem_s = f"{mem:.1f} GiB"
    except (OSError, AttributeError):
        mem_s = "?"
    try:
        load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        load = "?"
    blas = "?"
    try:
        cfg = np.show_config(mode="dicts")
        b = cfg["Build Dependencies"]["blas"]
        blas = f"{b.get('name', '?')} {b.get('version', '')}".strip()
    except Exception:
        pass
    return {
        "cpu": cpu,
        "isa": isa,
        "cores": str(os.cpu_count()),
        "memory": mem_s,
        "os": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "torch_threads": str(torch.get_num_threads()),
        "numpy_blas": blas,
        "load": load,
    }


def src_digest() -> str:
    """A digest of smplcore's source files, to notice when they change during a run."""
    import hashlib

    h = hashlib.sha1()
    for p in sorted((HERE.parent / "src" / "smplcore").rglob("*.py")):
        h.update(p.read_bytes())
    return h.hexdigest()[:12]


def versions() -> dict[str, str]:
    from importlib import metadata

    out = {}
    for dist in ("smplcore", "torch", "numpy", "scipy", "smplx", "chumpy-fixed", "body-models", "smplfitter"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = "not installed"
    try:
        out["smplcore git"] = (
            subprocess.run(
                ["git", "-C", str(HERE), "rev-parse", "--short", "HEAD"],
                capture_output=True,
                text=True,
                timeout=10,
            ).stdout.strip()
            or "?"
        )
        dirty = subprocess.run(
            ["git", "-C", str(HERE), "status", "--porcelain", "--", "../src"],
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
        if dirty:
            out["smplcore git"] += " (+ uncommitted changes in src/)"
    except (OSError, subprocess.SubprocessError):
        pass
    return out


# ------------------------------------------------------------------------------------------------
# Main


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "--quick",
        action="store_true",
        help="3 rounds, B=1 and 512 forward, B=64 forward+backward, SMPL and SMPL-X, "
        "smplcore-torch / smplx / smplfitter-torch only (< 2 min)",
    )
    ap.add_argument("--models", default=None, help=f"comma list of {ALL_MODELS} (default all; quick smpl,smplx)")
    ap.add_argument(
        "--contenders",
        default=None,
        help=f"comma list of {list(peers.CONTENDERS)} (default all; quick {','.join(QUICK_CONTENDERS)})",
    )
    ap.add_argument(
        "--open-peers",
        action="store_true",
        help="also run body-models and smplfitter on the open model (default: smplcore and smplx only)",
    )
    ap.add_argument("--modes", default=",".join(ALL_MODES), help="comma list of fwd, fwdbwd, joints")
    ap.add_argument("--batch-sizes", default=None, help="forward batch sizes (default 1,64,512; quick 1,512)")
    ap.add_argument(
        "--grad-batch-sizes", default=None, help="forward+backward batch sizes (default 1,64,512; quick 64)"
    )
    ap.add_argument("--joints-batch", type=int, default=4096)
    ap.add_argument(
        "--joints-ref-batch",
        type=int,
        default=None,
        help="batch of smplx's full forward that joints-only is compared with (default 64: smplx's best "
        "throughput on this machine, 1.5-2x its bodies/s at 512)",
    )
    ap.add_argument("--rounds", type=int, default=None, help="interleaved rounds per group (default 4; quick 3)")
    ap.add_argument("--sample-time", type=float, default=None, help="seconds per sample (default 0.15; quick 0.05)")
    ap.add_argument(
        "--entry-time",
        type=float,
        default=None,
        help="seconds of samples per contender and group before slow ones get fewer rounds (default 6; quick 2)",
    )
    ap.add_argument(
        "--max-call",
        type=float,
        default=None,
        help="peers slower than this many seconds per call are timed once (default 6; quick 2)",
    )
    ap.add_argument("--gap", type=float, default=0.3, help="idle seconds before a torch sample that follows NumPy code")
    ap.add_argument(
        "--time-budget",
        type=float,
        default=None,
        help="seconds for the timing part; past 60%% (85%%) of it the remaining groups get fewer rounds "
        "(default 660; quick 75)",
    )
    ap.add_argument(
        "--device",
        default="cpu",
        help="where the torch contenders run: cpu (default) or cuda "
        "(skips cleanly where there is no GPU; NumPy contenders and GEMM gauges stay on the CPU)",
    )
    ap.add_argument(
        "--compile",
        action="store_true",
        help="add smplcore-torch-compiled and smplx-compiled "
        "(torch.compile, Inductor); compilation happens in the warm-up calls",
    )
    ap.add_argument(
        "--dqs",
        action="store_true",
        help="add smplcore-torch-dqs and smplcore-numpy-dqs (skinning='dqs') and their time vs our LBS",
    )
    ap.add_argument("--threads", type=int, default=None, help="torch.set_num_threads(N) (default: torch's own)")
    ap.add_argument("--no-memory", action="store_true", help="skip the peak-memory subprocesses")
    ap.add_argument("--memory-batch", type=int, default=512)
    ap.add_argument("--output", default=None, help="results file (default bench/RESULTS.md; quick: none)")
    ap.add_argument("--cache", default=None, help="folder for the fake model files (default: temp dir)")
    ap.add_argument("--memory-probe", nargs=2, metavar=("MODEL", "JOBS"), help=argparse.SUPPRESS)
    return ap.parse_args(argv)


QUICK_CONTENDERS = ["smplcore-torch", "smplx", "smplfitter-torch"]


def _estimate(per_body: dict, model: str, mode: str, name: str, batch: int) -> float | None:
    """Seconds per call expected from the largest batch already seen (forward x 3 for forward+backward)."""

    def best(m):
        seen = [
            (b, t)
            for (mm, md, nm, b), t in per_body.items()
            if mm == model and md == m and nm == name and b >= max(16, batch // 8)
        ]
        return max(seen)[1] if seen else None

    t = best(mode)
    if t is None and mode == "fwdbwd":
        t = best("fwd")
        t = None if t is None else 3 * t
    return None if t is None else t * batch


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if args.memory_probe:
        model, spec = args.memory_probe
        jobs = [(c, m, int(b)) for c, m, b in (item.split(",") for item in spec.split(";"))]
        print(json.dumps(memory_probe(model, jobs, args.cache)))
        return 0

    warnings.filterwarnings("ignore")
    if args.device != "cpu":
        import torch

        if not args.device.startswith("cuda") or not torch.cuda.is_available():
            print(
                f"--device {args.device}: no such device on this machine (CUDA available: "
                f"{torch.cuda.is_available()}); nothing measured"
            )
            return 0
        peers.DEVICE = args.device
    if args.compile:
        peers.CONTENDERS.update(peers.COMPILED)
    if args.dqs:
        peers.CONTENDERS.update(peers.DQS)

    t_start = time.perf_counter()
    if args.threads:
        import torch

        torch.set_num_threads(args.threads)
    quick = args.quick
    budget = Budget(
        rounds=args.rounds or (3 if quick else 4),
        sample_time=args.sample_time or (0.05 if quick else 0.15),
        gap=args.gap,
        entry_time=args.entry_time or (2.0 if quick else 6.0),
        max_call=args.max_call or (2.0 if quick else 6.0),
    )
    full_rounds = budget.rounds
    time_budget = args.time_budget or (75.0 if quick else 660.0)
    fwd_sizes = [int(b) for b in (args.batch_sizes or ("1,512" if quick else "1,64,512")).split(",")]
    grad_sizes = [int(b) for b in (args.grad_batch_sizes or ("64" if quick else "1,64,512")).split(",")]
    ref_batch = args.joints_ref_batch or 64
    modes = [m for m in args.modes.split(",") if m]
    names = [c for c in (args.contenders or ",".join(QUICK_CONTENDERS if quick else peers.CONTENDERS)).split(",") if c]
    if args.compile and not args.contenders:
        names += [c for c in peers.COMPILED if c not in names]
    if args.dqs and not args.contenders:
        names += [c for c in peers.DQS if c not in names]
    if peers.DEVICE != "cpu":  # NumPy contenders have no device
        names = [c for c in names if peers.CONTENDERS[c].kind == "torch"]
    for c in names:
        if c not in peers.CONTENDERS:
            raise SystemExit(f"unknown contender {c!r}; known: {list(peers.CONTENDERS)}")
    models = [m for m in (args.models or ("smpl,smplx" if quick else ",".join(ALL_MODELS))).split(",") if m]
    for m in models:
        if m not in ALL_MODELS:
            raise SystemExit(f"unknown model {m!r}; known: {ALL_MODELS}")
    output = args.output or (None if quick else str(HERE / "RESULTS.md"))

    def log(s: str = "") -> None:
        print(s, flush=True)

    notes: list[str] = []
    mach, vers = machine_info(), versions()
    digest = src_digest()
    log(f"smplcore forward benchmark — {'quick' if quick else 'full'} mode, {budget.rounds} rounds, float32, CPU")
    log(
        f"  {mach['cpu']} ({mach['isa']}), {mach['cores']} cores, {mach['memory']}, torch threads "
        f"{mach['torch_threads']}, NumPy BLAS {mach['numpy_blas']}, load {mach['load']}"
    )
    log("  " + ", ".join(f"{k} {v}" for k, v in vers.items()))

    if "open" in models and not fixtures.open_model_available():
        msg = f"open model skipped: {fixtures.OPEN_MODEL} does not exist yet"
        log("  NOTE: " + msg)
        notes.append(msg)
        models.remove("open")

    # ---- load everything -----------------------------------------------------------------------
    loaded: dict[str, dict[str, peers.Contender]] = {}
    infos: dict[str, peers.ModelInfo] = {}
    load_errors: dict[tuple[str, str], str] = {}
    agreement: dict[tuple[str, str], tuple[float, float]] = {}
    for model in models:
        files = fixtures.prepare(model, args.cache)
        info = infos[model] = peers.model_info(model)
        loaded[model] = {}
        log(
            f"\n[{info.label}] V={info.num_verts} J={info.num_joints} K={info.num_coeffs} P={info.num_pose_features}"
            f"  {forward_flops(info) / 1e6:.1f} MFLOP/body  file {files.file}"
        )
        for name in names:
            if model == "open" and name in PEERS and not args.open_peers:
                continue
            try:
                loaded[model][name] = peers.CONTENDERS[name](info, files)
            except Exception as exc:
                load_errors[(model, name)] = f"{type(exc).__name__}: {exc}"[:300]
                log(f"  ! {name} cannot load it: {load_errors[(model, name)]}")
        # Same inputs, same outputs? (vertices and the J skeleton joints, against smplx)
        params = peers.canonical_params(info, 8, seed=123)
        outs = {}
        for name, c in loaded[model].items():
            try:
                v, j = c.forward(c.prepare(params))
                outs[name] = (peers.to_numpy(v), peers.to_numpy(j))
            except Exception as exc:
                load_errors[(model, name)] = f"forward failed: {type(exc).__name__}: {exc}"[:300]
                log(f"  ! {name} forward failed: {load_errors[(model, name)]}")
        for name in [n for n in list(loaded[model]) if (model, n) in load_errors]:
            del loaded[model][name]
        ref = outs.get("smplx")
        if ref is not None:
            parts = []
            for name, (v, j) in outs.items():
                dv = float(np.abs(v - ref[0]).max())
                dj = float(np.abs(j[:, : info.num_joints] - ref[1][:, : info.num_joints]).max())
                agreement[(model, name)] = (dv, dj)
                if name != "smplx":
                    parts.append(f"{name} {dv:.1e}/{dj:.1e}")
            log("  max |Δ| vs smplx on 8 bodies (vertices / skeleton joints, m): " + ", ".join(parts))

    # ---- time, group by group --------------------------------------------------------------------
    groups: list[Group] = []
    per_body: dict[tuple, float] = {}
    header = (
        f"  {'contender':30s} {'median':>10s} {'bodies/s':>10s} {'× smplx':>8s} {'GFLOP/s':>8s} {'share':>6s}"
        f" {'samples':>8s}"
    )
    for model in models:
        info = infos[model]
        plan = []
        if "fwd" in modes:
            plan += [("fwd", b) for b in fwd_sizes]
        if "fwdbwd" in modes:
            plan += [("fwdbwd", b) for b in grad_sizes]
        if "joints" in modes:
            plan += [("joints", args.joints_batch)]
        for mode, batch in plan:
            t_group = time.perf_counter()
            used = (t_group - t_start) / time_budget
            before = budget.rounds
            if used > 1.0:  # far behind: one sample each, slow peers once
                budget.min_samples = budget.rounds = 1
                budget.entry_time, budget.max_call = 2.0, min(budget.max_call, 2.0)
            elif used > 0.85:  # a slow spell on the machine: keep the run within its time
                budget.rounds, budget.entry_time = budget.min_samples, min(budget.entry_time, 3.0)
                budget.max_call = min(budget.max_call, 3.0)
            elif used > 0.6:
                budget.rounds = max(budget.min_samples, min(budget.rounds, full_rounds - 2))
            if budget.rounds != before:
                budget.reduced = f"rounds cut to {budget.rounds} from {info.label} {MODE_LABEL[mode]} B={batch} on"
                log(f"  (behind schedule: {budget.reduced})")
            params = peers.canonical_params(info, batch)
            entries = []
            for name, c in loaded[model].items():
                if (mode == "fwdbwd" and not c.grad) or (mode == "joints" and name == "smplx"):
                    continue
                if mode == "joints" and quick and name in PEERS:
                    continue
                x = c.prepare(params, grad=(mode == "fwdbwd"))
                fn = {"fwd": c.forward, "fwdbwd": c.fwd_bwd, "joints": c.joints}[mode]
                entries.append(Entry(name, c.kind, (lambda fn=fn, x=x: fn(x)), batch))
            if mode == "joints" and "smplx" in loaded[model]:
                c = loaded[model]["smplx"]
                x = c.prepare(peers.canonical_params(info, ref_batch))
                entries.append(
                    Entry(
                        "smplx",
                        "torch",
                        (lambda c=c, x=x: c.forward(x)),
                        ref_batch,
                        label=f"smplx (full forward, B={ref_batch})",
                    )
                )
            group = Group(model, mode, batch, entries)
            shape = gemm_shape(info, batch)
            if mode == "fwd" and batch >= 64:
                for kind in Gemm.kinds():
                    backend = "numpy" if kind == "numpy" else "torch"
                    if any(e.kind == backend for e in entries):
                        g = Gemm(kind, shape)
                        group.gemm[kind] = Entry(g.name, backend, g.run, batch, flops=g.flops)
            log(
                f"\n[{info.label}] {MODE_LABEL[mode]}, B={batch}"
                + (f"  (GEMM {shape[0]}×{shape[1]} @ {shape[1]}×{shape[2]} in the same rounds)" if group.gemm else "")
            )
            estimates = {e.name: _estimate(per_body, model, mode, e.name, e.batch) for e in entries}
            run_group(group, budget, {k: v for k, v in estimates.items() if v is not None}, log)
            groups.append(group)
            log(header)
            flops = forward_flops(info) * batch
            for e in group.entries:
                if e.samples:
                    per_body[(model, mode, e.name, e.batch)] = e.median / e.batch
                elif e.skipped and estimates.get(e.name):
                    per_body[(model, mode, e.name, e.batch)] = estimates[e.name] / e.batch
                if not e.samples:
                    log(f"  {e.shown:30s} {e.error or e.skipped}")
                    continue
                t = e.median
                gf = flops / t / 1e9 if mode == "fwd" else float("nan")
                ceil = ceiling(group)
                share = gf / ceil if math.isfinite(ceil) else float("nan")
                ratio = ratio_to(group, e.name) if e.name != "smplx" else 1.0
                log(
                    f"  {e.shown:30s} {fmt_time(t):>10s} {fmt_rate(e.batch / t):>10s} {fmt_num(ratio, 2):>8s} "
                    f"{fmt_num(gf, 1):>8s} {fmt_num(100 * share, 0, '%'):>6s} "
                    + ("    once" if e.once else f"{len(e.samples):>4d}×{e.n:<3d}")
                )
            for kind, ge in group.gemm.items():
                log(
                    f"  {ge.name:30s} {fmt_time(ge.median):>10s} {'':>10s} {'':>8s} "
                    f"{fmt_num(gemm_gflops(group, kind), 1):>8s} {'':>6s} {len(ge.samples):>4d}×{ge.n:<3d}"
                )
            log(f"  ({time.perf_counter() - t_group:.0f} s; {time.perf_counter() - t_start:.0f} s elapsed)")

    # ---- peak memory -------------------------------------------------------------------------------
    memory: dict[tuple, dict] = {}
    if not args.no_memory and "fwd" in modes:
        jobs = []
        for model in models:
            g = _group(groups, model, "fwd", args.memory_batch)
            ran = {e.name for e in g.entries if e.samples and not e.once} if g else set(loaded[model])
            late = time.perf_counter() - t_start > time_budget  # behind schedule: smplcore and smplx only
            for name in loaded[model]:
                if name in ran and (not (quick or late) or name in ("smplcore-torch", "smplx")):
                    jobs.append((model, name, "fwd", args.memory_batch))
            if "joints" in modes and not quick:
                for name in ("smplcore-torch", "smplcore-numpy"):
                    if name in loaded[model]:
                        jobs.append((model, name, "joints", args.joints_batch))
        log(
            f"\nPeak memory of one call (RSS high-water mark above the RSS before it; a fresh process per model, "
            f"{len(jobs)} measurements)"
        )
        memory = measure_memory(jobs, args.cache, log)

    elapsed = time.perf_counter() - t_start
    targets = evaluate_targets(groups, infos, memory, args)
    log("\nTargets (smplcore-torch)")
    log(f"  {'target':58s} {'model':7s} {'measured':>22s}  result")
    for t in targets:
        log(f"  {t['target']:58s} {t['model']:7s} {t['measured']:>22s}  {t['result']}")
    log(f"\nTotal {elapsed:.0f} s")

    if src_digest() != digest:
        msg = (
            "smplcore's source files changed during this run (someone edited src/), so its numbers may mix "
            "two versions of the engine: rerun"
        )
        log("  WARNING: " + msg)
        notes.append(msg)
    try:
        mach["load_end"] = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        mach["load_end"] = "?"
    if output:
        text = render_markdown(
            args,
            argv,
            quick,
            budget,
            ref_batch,
            mach,
            vers,
            infos,
            groups,
            memory,
            agreement,
            load_errors,
            targets,
            notes,
            elapsed,
            fwd_sizes,
            grad_sizes,
            modes,
        )
        Path(output).write_text(text)
        log(f"wrote {output}")
    return 0


# ------------------------------------------------------------------------------------------------
# Targets


def _group(groups, model, mode, batch) -> Group | None:
    return next((g for g in groups if g.model == model and g.mode == mode and g.batch == batch), None)


def _entry(group: Group | None, name: str) -> Entry | None:
    if group is None:
        return None
    return next((e for e in group.entries if e.name == name and e.samples), None)


def gemm_limit(group: Group | None) -> float:
    """smplx's time over the best blend-shape GEMM's: the speed-up of a forward that were only its GEMM."""
    if group is None:
        return float("nan")
    ref = _entry(group, "smplx")
    best = [e.median for e in group.gemm.values() if e.samples]
    return ref.median / min(best) if ref is not None and best else float("nan")


def fwd_batches(groups: list[Group], model: str) -> list[int]:
    """The forward batch sizes timed for ``model``."""
    return sorted({g.batch for g in groups if g.model == model and g.mode == "fwd"})


def evaluate_targets(groups: list[Group], infos: dict, memory: dict, args) -> list[dict]:
    out = []
    core = "smplcore-torch"

    def add(target, model, value, ok, fmt):
        if value is None or not math.isfinite(value):
            res = "—"
        else:
            res = "info" if ok is None else ("PASS" if ok(value) else "FAIL")
        out.append(
            {
                "target": target,
                "model": infos[model].label if model in infos else model,
                "measured": "not measured" if res == "—" else fmt(value),
                "result": res,
                "value": value,
            }
        )

    for model in infos if args.dqs else ():  # dual-quaternion skinning against our LBS: time(DQS) / time(LBS)
        for kernel_name, dqs_name in ((core, "smplcore-torch-dqs"), ("smplcore-numpy", "smplcore-numpy-dqs")):
            for batch in fwd_batches(groups, model):
                g = _group(groups, model, "fwd", batch)
                add(
                    f"{dqs_name} forward B={batch} ≤ 1.5× {kernel_name}'s time",
                    model,
                    ratio_to(g, kernel_name, dqs_name) if g else None,
                    lambda v: v <= 1.5,
                    lambda v: f"{v:.2f}×",
                )
        g = _group(groups, model, "fwdbwd", 64)
        add(
            "smplcore-torch-dqs forward+backward B=64 vs smplcore-torch's time",
            model,
            ratio_to(g, core, "smplcore-torch-dqs") if g else None,
            None,
            lambda v: f"{v:.2f}×",
        )

    big = 512
    for model in [m for m in ("smpl", "smplh", "smplx") if m in infos]:
        g = _group(groups, model, "fwd", big)
        limit = gemm_limit(g)
        add(
            f"forward B={big} ≥ 5× smplx",
            model,
            ratio_to(g, core) if g else None,
            lambda v: v >= 5,
            lambda v, limit=limit: f"{v:.2f}×" + (f" (GEMM-bound limit {limit:.1f}×)" if math.isfinite(limit) else ""),
        )
        if g is not None:
            peer_entries = [e for e in g.entries if e.name in PEERS and e.samples]
            best = min(peer_entries, key=lambda e: e.median) if peer_entries else None
            val = ratio_to(g, core, best.name) if best else None
            add(
                f"forward B={big} ≥ fastest peer" + (f" ({best.name})" if best else ""),
                model,
                val,
                lambda v: v >= 1.0,
                lambda v: f"{v:.2f}×",
            )
            ce = _entry(g, core)
            share = (forward_flops(infos[model]) * big / ce.median / 1e9 / ceiling(g)) if ce else None
            add(
                f"forward B={big}: share of GEMM ceiling ≥ 40%",
                model,
                share,
                lambda v: v >= 0.40,
                lambda v: f"{100 * v:.0f}%",
            )
        g1 = _group(groups, model, "fwd", 1)
        r1 = ratio_to(g1, core) if g1 else None
        add(
            "B=1 latency ≤ 0.5× smplx",
            model,
            None if r1 is None else 1 / r1,
            lambda v: v <= 0.5,
            lambda v, r1=r1: f"{v:.2f}× ({r1:.1f}× faster)",
        )
        gj = _group(groups, model, "joints", args.joints_batch)
        ref = next((e.batch for e in gj.entries if e.name == "smplx"), None) if gj else None
        add(
            f"joints only B={args.joints_batch} ≥ 50× smplx full forward" + (f" (bodies/s, B={ref})" if ref else ""),
            model,
            ratio_to(gj, core) if gj else None,
            lambda v: v >= 50,
            lambda v: f"{v:.2f}×",
        )
        gb = _group(groups, model, "fwdbwd", 64)
        add(
            "forward+backward B=64 ≥ 3× smplx",
            model,
            ratio_to(gb, core) if gb else None,
            lambda v: v >= 3,
            lambda v: f"{v:.2f}×",
        )
        mc = memory.get((model, core, "fwd", args.memory_batch), {}).get("peak_mib")
        ms = memory.get((model, "smplx", "fwd", args.memory_batch), {}).get("peak_mib")
        mval = mc / ms if mc is not None and ms else None
        add(
            f"peak memory B={args.memory_batch} ≤ 0.5× smplx",
            model,
            mval,
            lambda v: v <= 0.5,
            lambda v, mc=mc, ms=ms: f"{v:.2f}× ({mc:.0f}/{ms:.0f} MiB)",
        )
    return out


# ------------------------------------------------------------------------------------------------
# RESULTS.md


def render_markdown(
    args,
    argv,
    quick,
    budget: Budget,
    ref_batch,
    mach,
    vers,
    infos,
    groups,
    memory,
    agreement,
    load_errors,
    targets,
    notes,
    elapsed,
    fwd_sizes,
    grad_sizes,
    modes,
) -> str:
    rounds, sample_time = args.rounds or (3 if quick else 4), budget.sample_time
    given = list(sys.argv[1:] if argv is None else argv)
    cmd = " ".join(["python bench/forward.py", *given])
    L: list[str] = []
    w = L.append
    w("# Forward-pass benchmark")
    w("")
    w(
        f"Written by `bench/forward.py` on {_dt.datetime.now().strftime('%Y-%m-%d %H:%M')} "
        f"({'quick' if quick else 'full'} mode, {rounds} rounds, {elapsed / 60:.1f} min). Rerun with:"
    )
    w("")
    w("```sh")
    w(". /work/venv/bin/activate  # or any env with `pip install -e .[bench]`")
    w(cmd)
    w("```")
    w("")
    w(
        "float32, CPU, fake official model files of real size from `tests/fakes.py` (random numbers, real "
        "shapes: timings are those of the real files), and smplcore's open model. Each group (model × mode × "
        "batch) runs all contenders interleaved, their order rotating each round; each sample is "
        f"≥ {sample_time:g} s of back-to-back calls after a {args.gap:g} s idle gap next to NumPy code "
        "(OpenBLAS threads spin after a call and slow what runs next). Times are medians over rounds; "
        '"× smplx" is the median over rounds of the per-round ratio, so that a slow spell on this shared '
        "machine hits both sides of a ratio."
    )
    w("")
    w("## Machine")
    w("")
    w("| | |")
    w("| --- | --- |")
    for k, label in (
        ("cpu", "CPU"),
        ("isa", "vector ISA"),
        ("cores", "cores"),
        ("memory", "RAM"),
        ("os", "OS"),
        ("python", "Python"),
        ("torch_threads", "torch threads"),
        ("numpy_blas", "NumPy BLAS"),
        ("load", "load average at start"),
        ("load_end", "load average at end"),
    ):
        w(f"| {label} | {mach[k]} |")
    w("")
    w("Versions: " + ", ".join(f"{k} {v}" for k, v in vers.items()) + ".")
    w("")
    if budget.reduced:
        notes = [*notes, f"the machine was slow during this run, so to stay within --time-budget the {budget.reduced}"]
    if notes:
        for n in notes:
            w(f"**Note:** {n}.")
        w("")

    w("## Targets (smplcore, torch)")
    w("")
    w("| target | model | measured | result |")
    w("| --- | --- | --- | --- |")
    for t in targets:
        w(f"| {t['target']} | {t['model']} | {t['measured']} | {t['result']} |")
    w("")
    w(
        "The GEMM-bound limit is smplx's time over the time of the blend-shape GEMM alone (B × (K+P) @ (K+P) × 3V, "
        "the best of torch (MKL), oneDNN and NumPy): the speed-up over smplx of a forward that did nothing but "
        "that GEMM. "
        '"fastest peer" = the fastest of body-models and smplfitter, NumPy or torch backend, in the same group. '
        "The B=1 latency is smplcore's time over smplx's. Joints only: smplcore with `return_verts=False` "
        "(skeleton and extra vertex joints, without building the mesh) against smplx's full forward (smplx has no "
        f"joints-only path) at B={ref_batch}, in bodies/s. Peak memory: see below."
    )
    w("")

    w("## Models and contenders")
    w("")
    w("| model | V | J | K (coefficients) | P (pose features) | FLOPs / body | file |")
    w("| --- | ---: | ---: | ---: | ---: | ---: | --- |")
    for key, info in infos.items():
        src = {
            "smpl": "fakes.write_smpl(neutral, v1.1, pkl)",
            "smplh": "fakes.write_smplh(neutral, pkl)",
            "smplx": "fakes.write_smplx(neutral, npz, v1.1)",
            "open": "src/smplcore/data/open_model.npz (as SMPL-layout pkl for the others)",
        }[key]
        w(
            f"| {info.label} | {info.num_verts} | {info.num_joints} | {info.num_coeffs} | {info.num_pose_features} | "
            f"{forward_flops(info) / 1e6:.1f} M | {src} |"
        )
    w("")
    w(
        "All contenders get the same bodies: 10 betas (SMPL-X: + 10 expression coefficients, zero), random "
        "axis-angle poses, full (non-PCA) hand poses with a flat hand mean. Contenders:"
    )
    w("")
    w("* **smplcore-torch** `smplcore.create(...)(**params)`, **smplcore-numpy** `smplcore.BodyModel(...)(**params)`;")
    w("* **smplx** 0.1.28 `smplx.create(root, model_type=..., use_pca=False, flat_hand_mean=True)`;")
    w(
        "* **body-models** `body_models.<model>.{numpy,torch}.<MODEL>(model_path=file)`: `prepare_identity` + "
        "`prepare_pose` once, the mesh from them (its public `forward_vertices` + `forward_skeleton` would run the "
        "kinematic chain twice; this is its best case for vertices + joints); joints only = `forward_skeleton` "
        "(skeleton joints only). It uses sparse (compact) skinning weights;"
    )
    w(
        "* **smplfitter** `smplfitter.{np,pt}.BodyModel(name, gender, model_root=..., num_betas=10)`; it needs its own "
        "file names (`basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl`, `SMPLX_NEUTRAL.npz`, `SMPLH_{male,female}.pkl`: the "
        "SMPL+H neutral file is linked as `SMPLH_male.pkl`) and a `kid_template.npy` (all-zero placeholder, its own "
        'convention for "no kid template"); joints only = `return_vertices=False` (skeleton joints only). For '
        "SMPL-X it has no separate expression input, so it evaluates K=10 instead of 20."
    )
    w(
        "* The open model has no pose correctives: smplcore skips the pose blend, while the others run it "
        "on all-zero `posedirs` (they have no way to leave it out), so its ratios are not like-for-like."
    )
    w("")
    if load_errors:
        w("Could not run:")
        w("")
        for (model, name), err in load_errors.items():
            w(f"* {name} on {infos[model].label if model in infos else model}: `{err}`")
        w("")
    w("Agreement with smplx on the same 8 bodies (max |Δ| in metres, vertices / the J skeleton joints):")
    w("")
    names = sorted({n for (_, n) in agreement}, key=lambda n: list(peers.CONTENDERS).index(n))
    w("| model | " + " | ".join(n for n in names if n != "smplx") + " |")
    w("| --- |" + " --- |" * (len(names) - 1))
    for key, info in infos.items():
        cells = []
        for n in names:
            if n == "smplx":
                continue
            a = agreement.get((key, n))
            cells.append("—" if a is None else f"{a[0]:.1e} / {a[1]:.1e}")
        w(f"| {info.label} | " + " | ".join(cells) + " |")
    w("")

    w("## Results")
    w("")
    w(
        "Median time per call; bodies/s = B / time; × smplx = speed-up over smplx (higher is better); "
        "GFLOP/s from the FLOP count below; share = that over the machine's float32 GEMM ceiling: the faster of "
        "the torch and NumPy GEMMs of the same size, measured in the same rounds; peak = memory of one call "
        f"(B={args.memory_batch} forward, B={args.joints_batch} joints only); samples = rounds × calls per sample "
        "(slow contenders get fewer rounds; peers slower than "
        f"{budget.max_call:g} s per call are timed once or not at all). In the joints-only groups the smplx row is its "
        f"full forward at B={ref_batch} and × smplx compares bodies/s."
    )
    for key, info in infos.items():
        w("")
        w(f"### {info.label} (V={info.num_verts}, J={info.num_joints})")
        for g in [g for g in groups if g.model == key]:
            w("")
            title = f"**{MODE_LABEL[g.mode]}, B={g.batch}**"
            if g.gemm:
                m, k, n = gemm_shape(info, g.batch)
                gem = ", ".join(f"{kind} {gemm_gflops(g, kind):.1f}" for kind in g.gemm)
                title += f" — GEMM ({m}×{k}) @ ({k}×{n}): {gem} GFLOP/s"
            w(title)
            w("")
            show_share = g.mode == "fwd"
            mem_mode = (
                "fwd"
                if g.mode == "fwd" and g.batch == args.memory_batch
                else ("joints" if g.mode == "joints" else None)
            )
            cols = ["contender", "median", "bodies/s", "× smplx"]
            if show_share:
                cols += ["GFLOP/s", "share of GEMM"]
            if mem_mode:
                cols += ["peak MiB"]
            cols += ["samples"]
            if g.mode == "joints":
                cols += ["what is computed"]
            w("| " + " | ".join(cols) + " |")
            w("| --- |" + " ---: |" * (len(cols) - 1 - (g.mode == "joints")) + (" --- |" if g.mode == "joints" else ""))
            for e in g.entries:
                if not e.samples:
                    why = f"error: {e.error}" if e.error else e.skipped
                    w(f"| {e.shown} | {why} |" + " |" * (len(cols) - 2))
                    continue
                t = e.median
                row = [
                    e.shown,
                    fmt_time(t),
                    fmt_rate(e.batch / t),
                    "1" if e.name == "smplx" and g.mode != "joints" else fmt_num(ratio_to(g, e.name), 2),
                ]
                if g.mode == "joints" and e.name == "smplx":
                    row[3] = "1"
                if show_share:
                    gf = forward_flops(info) * g.batch / t / 1e9
                    ceil = ceiling(g)
                    row += [fmt_num(gf, 1), fmt_num(100 * gf / ceil, 0, "%") if math.isfinite(ceil) else "—"]
                if mem_mode:
                    mm = memory.get((key, e.name, mem_mode, e.batch), {})
                    row += [fmt_num(mm["peak_mib"], 0) if "peak_mib" in mm else "—"]
                row += ["1 call (too slow to repeat)" if e.once else f"{len(e.samples)} × {e.n}"]
                if g.mode == "joints":
                    row += [
                        "full forward (smplx has no joints-only path)"
                        if e.name == "smplx"
                        else peers.CONTENDERS[e.name].joints_note
                    ]
                w("| " + " | ".join(row) + " |")
            for kind, ge in g.gemm.items():
                if ge.samples:
                    w(
                        f"| *{ge.name}* | {fmt_time(ge.median)} | | | {fmt_num(gemm_gflops(g, kind), 1)} | 100% |"
                        + (" |" if mem_mode else "")
                        + f" {len(ge.samples)} × {ge.n} |"
                    )
    w("")
    w("## Method")
    w("")
    w(
        f"* **FLOPs** (multiply-add = 2) per body: `{FLOP_FORMULA}` — shape and pose blend shapes as one GEMM "
        "(K coefficients, P = 9(J−1) pose features, 3V coordinates), blending the J 3×4 skinning transforms per "
        "vertex with dense weights (12·J multiply-adds per vertex), then applying them (3×3 matrix-vector product + "
        "translation, 18) and adding template and offsets (6). Joint regression from precomputed joint bases, "
        "Rodrigues and the kinematic chain are < 1% and left out. The same count is used for every contender "
        "(smplx does more: a dense J_regressor over all vertices and 4×4 transforms; body-models fewer: sparse "
        "skinning), so GFLOP/s compares time for the same useful work."
    )
    w(
        "* **GEMM ceiling**: `A @ B` with A (B × (K+P)) and B ((K+P) × 3V), float32, timed in the same rounds as "
        "the B≥64 forwards: with torch and with NumPy, output allocated as in a forward, and with torch into one "
        "preallocated output (`gemm-torch-out`: no page faults), and with oneDNN on a packed B (`gemm-onednn`, "
        "where torch has oneDNN: what smplcore runs); the ceiling is the fastest of them. (NumPy "
        "asks the kernel for transparent huge pages for large arrays, torch does not: with THP in `madvise` "
        "mode, as here, a fresh torch output is page-faulted in 4 KiB at a time, which costs ~0.3-1 ms per MB "
        "on this VM; smplcore allocates its large buffers through NumPy for that reason.) The open model "
        "has P=0, so its ceiling uses the SMPL-sized inner dimension 217."
    )
    w(
        "* **Peak memory**: a fresh subprocess per model, started with glibc's mmap threshold fixed at 128 KiB "
        "(large blocks come from mmap and go back to the kernel on free, so one measurement cannot hide in memory "
        "freed by another); for each contender in turn: a warm-up call, `gc.collect()` and `malloc_trim(0)`, the "
        "kernel's RSS high-water mark reset to the current RSS (`/proc/self/clear_refs` = 5), one call: "
        "peak = VmHWM − VmRSS before the call (inputs excluded, output included). Checked: the same numbers "
        "(±1%) as one process per contender, in any order."
    )
    w(
        "* **Interference**: on 2 shared cores, NumPy's OpenBLAS threads keep spinning ~0.1 s after a call; every "
        f"torch sample that follows NumPy code is preceded by a {args.gap:g} s idle gap (10 ms otherwise). Other "
        "jobs on the machine slow torch's 2-thread parallel regions most (a thread waits for a time slice at "
        "every barrier), so a busy spell moves ratios too; the GEMM GFLOP/s in each group's header is the gauge: "
        "groups where it drops well below the others ran during such a spell."
    )
    w(
        f"* Sizes: forward B ∈ {fwd_sizes}, forward+backward B ∈ {grad_sizes} (loss = vertices.sum() + "
        f"joints.sum(), gradients for pose and betas), joints only B = {args.joints_batch}; modes {modes}."
    )
    w("")
    return "\n".join(L)


if __name__ == "__main__":
    sys.exit(main())
