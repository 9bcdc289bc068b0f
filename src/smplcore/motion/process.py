"""Whole motion datasets to joints (and meshes): resumable, safe, parallel, optionally on Ray.

:func:`process_tree` walks a folder of AMASS-style ``.npz`` sequences and writes one output per
input, mirroring the tree, plus ``manifest.json``. It is what ``smplcore process`` runs.

Guarantees
----------
* **Atomic outputs.** Each output is written under a hidden temporary name in its final folder,
  flushed to disk, then renamed; a run killed at any moment leaves either the complete output or
  none. Leftover temporary files (``.NAME.<pid>-<hex>.smplcore-tmp``) are removed by the next run.
* **Resumable.** An output that exists is complete, and is not recomputed (``overwrite=True``
  recomputes everything). A rerun with settings that would change the outputs is refused: the
  settings are kept in the manifest.
* **Never aborts on bad data.** A truncated, inconsistent or NaN-holding input (or one whose
  gendered model is missing) is reported with its path and reason, counted, recorded in the
  manifest and skipped; the summary's ``exit_code`` is 1 when anything was skipped.
* **One writer.** A lock file in the output folder stops two runs from writing the same tree.

Parallelism: ``workers`` processes (forked from a fork server, or spawned; one BLAS/OpenMP thread
each, torch threads = CPUs / workers), each keeping one loaded model per (model type, gender) and
evaluating frames in chunks; files are handed out largest first. ``ray_address`` runs the same
per-file function as Ray tasks (on a cluster the input and output folders must be on a file
system every node sees).
"""

from __future__ import annotations

import contextlib
import fnmatch
import json
import math
import os
import re
import secrets
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass, field, fields
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

MANIFEST_NAME = "manifest.json"
LOCK_NAME = ".smplcore-process.lock"
TMP_SUFFIX = ".smplcore-tmp"
DEFAULT_EXCLUDE = ("shape.npz",)  # AMASS's per-subject shape files: betas and gender, no motion
_THREAD_VARS = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)


class ProcessError(ValueError):
    """The job cannot start: bad folders or settings, a locked or incompatible output folder."""


# --------------------------------------------------------------------------------------------------
# Settings


@dataclass(frozen=True)
class ProcessOptions:
    """What to compute for each sequence and how to store it.

    Attributes
    ----------
    model_path : model file or folder (see :func:`smplcore.motion.models.find_model_file`); None
        for the packaged open model.
    model_type : model to evaluate; None: the type the motion file names (``open`` without a
        ``model_path``). Another type is driven joint by joint by name (e.g. SMPL+H data on ``open``).
    gender : ``file`` (the gendered model the file names), ``humanml3d`` (male if the file says
        male, else female) or a fixed ``neutral``/``male``/``female``.
    ext : model file extension to look for in a folder (None: npz, then pkl).
    num_betas : shape coefficients used (None: all the model file holds).
    fps : output frame rate (None: keep the source rate); ``resample`` is the method
        (``interp``, ``nearest`` or ``stride``, see :mod:`smplcore.motion.resample`).
    vertices : also write the mesh vertices (``.npz`` only).
    extra_joints : keep the model's extra vertex joints and landmarks after the skeleton joints.
    num_joints : keep only the first ``num_joints`` joints (HumanML3D uses 22).
    axes : output axes as three of ``x y z`` with optional signs, e.g. ``xzy`` (HumanML3D) or
        ``x,-z,y``; applied to joints and vertices.
    dtype : stored dtype, ``float32``, ``float16`` or ``float64`` (float64 also computes in float64).
    format : ``npz`` (joints, optional vertices and metadata) or ``npy`` (joints only, HumanML3D).
    compress : write compressed ``.npz``.
    backend : ``auto`` (NumPy, the fastest on a CPU), ``numpy`` or ``torch``.
    chunk : frames per forward call (None: the backend's best, see
        :class:`~smplcore.motion.models.Evaluator`).
    """

    model_path: str | None = None
    model_type: str | None = None
    gender: str = "file"
    ext: str | None = None
    num_betas: int | None = None
    fps: float | None = None
    resample: str = "interp"
    vertices: bool = False
    extra_joints: bool = False
    num_joints: int | None = None
    axes: str = "xyz"
    dtype: str = "float32"
    format: str = "npz"
    compress: bool = False
    backend: str = "auto"
    chunk: int | None = None

    def __post_init__(self) -> None:
        from smplcore.family.specs import get_spec
        from smplcore.motion.models import GENDER_RULES
        from smplcore.motion.resample import METHODS

        if self.model_path is not None:
            object.__setattr__(self, "model_path", str(Path(self.model_path).expanduser().resolve()))
        if self.model_type is not None:
            object.__setattr__(self, "model_type", get_spec(self.model_type).model_type)
        if self.gender not in GENDER_RULES:
            raise ValueError(f"gender: expected one of {GENDER_RULES}, got {self.gender!r}")
        if self.resample not in METHODS:
            raise ValueError(f"resample: expected one of {METHODS}, got {self.resample!r}")
        if self.fps is not None:
            if not (math.isfinite(self.fps) and self.fps > 0):
                raise ValueError(f"fps: expected a positive frame rate, got {self.fps}")
            object.__setattr__(self, "fps", float(self.fps))
        if self.dtype not in ("float32", "float16", "float64"):
            raise ValueError(f"dtype: expected float32, float16 or float64, got {self.dtype!r}")
        if self.format not in ("npz", "npy"):
            raise ValueError(f"format: expected 'npz' or 'npy', got {self.format!r}")
        if self.format == "npy" and self.vertices:
            raise ValueError("format: 'npy' holds the joints only; use format 'npz' to write vertices")
        for name in ("num_betas", "num_joints"):
            value = getattr(self, name)
            if value is not None and (not isinstance(value, int) or value < (0 if name == "num_betas" else 1)):
                raise ValueError(f"{name}: expected a positive integer, got {value!r}")
        if self.chunk is not None and self.chunk < 1:
            raise ValueError(f"chunk: expected a positive number of frames, got {self.chunk}")
        parse_axes(self.axes)

    @property
    def suffix(self) -> str:
        return "." + self.format

    def output_settings(self) -> dict[str, Any]:
        """The settings that decide the outputs' contents (kept in the manifest, checked on resume)."""
        out = asdict(self)
        for name in ("backend", "chunk"):  # how, not what
            out.pop(name)
        return out


# A recipe is a set of option values; explicit options win over the recipe's.
RECIPES: dict[str, dict[str, Any]] = {
    # HumanML3D's raw_pose_processing: gendered SMPL+H (neutral files go to the female model), 10
    # betas, every int(fps / 20)-th frame, the 52 skeleton joints, y and z swapped, one .npy per file.
    "humanml3d": {
        "model_type": "smplh",
        "gender": "humanml3d",
        "num_betas": 10,
        "fps": 20.0,
        "resample": "stride",
        "axes": "xzy",
        "format": "npy",
        "extra_joints": False,
    },
}


def options_from_recipe(recipe: str | None, **explicit: Any) -> ProcessOptions:
    """:class:`ProcessOptions` from a recipe name (or None) and explicit values (None = not given)."""
    values: dict[str, Any] = {}
    if recipe is not None:
        if recipe not in RECIPES:
            raise ValueError(f"recipe: expected one of {sorted(RECIPES)}, got {recipe!r}")
        values.update(RECIPES[recipe])
    known = {f.name for f in fields(ProcessOptions)}
    unknown = set(explicit) - known
    if unknown:
        raise TypeError(f"unknown option(s) {sorted(unknown)}")
    values.update({k: v for k, v in explicit.items() if v is not None})
    return ProcessOptions(**values)


def parse_axes(axes: str) -> tuple[list[int], np.ndarray]:
    """``xzy`` / ``x,-z,y`` → (source column of each output axis, sign of each)."""
    tokens = re.findall(r"([+-]?)([xyz])", axes.lower())
    rest = re.sub(r"[+-]?[xyz]|[\s,]", "", axes.lower())
    cols = ["xyz".index(t[1]) for t in tokens]
    if rest or sorted(cols) != [0, 1, 2]:
        raise ValueError(
            f"axes: expected each of x, y, z once with optional signs (e.g. 'xzy', 'x,-z,y'), got {axes!r}"
        )
    return cols, np.array([-1.0 if t[0] == "-" else 1.0 for t in tokens])


def _apply_axes(points: np.ndarray, axes: str) -> np.ndarray:
    cols, signs = parse_axes(axes)
    if cols == [0, 1, 2] and (signs > 0).all():
        return points
    out = points[..., cols]
    return out * signs.astype(points.dtype) if (signs < 0).any() else out


# --------------------------------------------------------------------------------------------------
# One file


@dataclass(frozen=True)
class Task:
    """One input file: its absolute path, its path relative to the input root, its output."""

    source: str
    relative: str
    output: str
    size: int = 0


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def atomic_write(path: Path, write: Callable[[Any], None]) -> None:
    """Write ``path`` through ``write(file)`` under a temporary name, fsync, then rename into place."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}-{secrets.token_hex(4)}{TMP_SUFFIX}")
    try:
        with open(tmp, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


@dataclass
class WorkerState:
    """What a worker keeps between files: the options, the loaded models, the evaluator."""

    options: ProcessOptions
    cache: Any
    evaluator: Any

    @classmethod
    def build(cls, options: ProcessOptions) -> WorkerState:
        from smplcore.motion.models import Evaluator, ModelCache

        dtype = np.float64 if options.dtype == "float64" else np.float32
        cache = ModelCache(
            options.model_path,
            num_betas=options.num_betas,
            ext=options.ext,
            backend=options.backend,
            dtype=dtype,
            vertices=options.vertices,
        )
        return cls(options, cache, Evaluator(chunk=options.chunk))


def process_file(task: Task, state: WorkerState) -> dict[str, Any]:
    """Process one sequence; never raises for bad data: returns a manifest entry (status done/skipped)."""
    from smplcore.motion import resample as rs
    from smplcore.motion.models import pick_gender
    from smplcore.motion.sequence import load_motion

    options = state.options
    start = time.perf_counter()
    entry: dict[str, Any] = {"input": task.relative, "output": None, "status": "skipped"}
    try:
        motion = load_motion(task.source)
        entry.update(source_frames=motion.num_frames, source_fps=float(motion.fps))
        if options.fps is not None:
            p = rs.plan(motion.num_frames, motion.fps, options.fps, options.resample)
            motion = motion.take(p)
            positions = p.source_position
        else:
            positions = np.arange(motion.num_frames, dtype=np.float64)
        if motion.num_frames == 0:
            raise ValueError("the sequence has no frames")
        model_type = options.model_type or (motion.model_type if options.model_path else "open")
        gender = pick_gender(motion.gender, options.gender)
        loaded = state.cache.get(model_type, gender)
        joints, verts = state.evaluator.run(
            motion, loaded, vertices=options.vertices, skeleton_only=not options.extra_joints
        )
        names = list(loaded.model.joint_names)
        keep = len(names) if options.extra_joints else len(loaded.model.skeleton_joint_names)
        if options.num_joints is not None:
            if options.num_joints > keep:
                raise ValueError(
                    f"num_joints: {options.num_joints} asked, but the {loaded.model_type} model gives {keep} joints"
                )
            keep = options.num_joints
        joints, names = joints[:, :keep], names[:keep]
        if not np.isfinite(joints).all() or (verts is not None and not np.isfinite(verts).all()):
            raise ValueError("the model gave non-finite joints (extreme poses or translations in the file)")
        joints = _apply_axes(joints, options.axes)
        verts = None if verts is None else _apply_axes(verts, options.axes)
        dtype = np.dtype(options.dtype)
        joints = joints.astype(dtype, copy=False)
        if options.format == "npy":
            atomic_write(Path(task.output), lambda fh: np.save(fh, joints))
        else:
            arrays: dict[str, np.ndarray] = {
                "joints": joints,
                "joint_names": np.array(names),
                "fps": np.array(float(motion.fps)),
                "source": np.array(task.relative),
                "source_fps": np.array(float(entry["source_fps"])),
                "source_frame": positions.astype(np.float64),
                "model_type": np.array(loaded.model_type),
                "model_file": np.array(loaded.path.name),
                "gender": np.array(loaded.gender),
                "betas": np.asarray(motion.betas[: loaded.num_betas], dtype=np.float64),
                "axes": np.array(options.axes),
            }
            if verts is not None:
                arrays["vertices"] = verts.astype(dtype, copy=False)
                arrays["faces"] = np.asarray(loaded.model.faces, dtype=np.int32)
            save = np.savez_compressed if options.compress else np.savez
            atomic_write(Path(task.output), lambda fh: save(fh, **arrays))
        entry.update(
            status="done",
            output=_relative_output(task),
            frames=int(joints.shape[0]),
            fps=float(motion.fps),
            joints=int(joints.shape[1]),
            model_type=loaded.model_type,
            gender=loaded.gender,
            model_file=str(loaded.path),
        )
    except Exception as exc:  # noqa: BLE001 -- any failure of one file is reported, never fatal
        entry["reason"] = _reason(exc)
    entry["seconds"] = round(time.perf_counter() - start, 4)
    return entry


def _relative_output(task: Task) -> str:
    return str(Path(task.relative).with_suffix(Path(task.output).suffix))


def _reason(exc: BaseException) -> str:
    from smplcore.errors import ModelFileError, ShapeError

    if isinstance(exc, (ModelFileError, ShapeError, ValueError)):
        return str(exc)
    return f"{type(exc).__name__}: {exc}"


# --------------------------------------------------------------------------------------------------
# Workers (processes and Ray tasks)

_STATE: WorkerState | None = None
_RAY_STATES: dict[str, WorkerState] = {}


def _watch_parent(alive: Any) -> None:
    """Exit when the run's process dies: ``alive`` is the read end of a pipe only that process writes to,
    so it reads end-of-file exactly when the run is gone (however it died; a killed run must not leave
    workers behind)."""
    try:
        alive.recv()
    except BaseException:  # noqa: BLE001 -- EOFError: the run is gone
        pass
    os._exit(3)


def _init_worker(options: ProcessOptions, threads: int, alive: Any) -> None:
    global _STATE
    if alive is not None:
        threading.Thread(target=_watch_parent, args=(alive,), daemon=True).start()
    # Ctrl-C goes to the whole process group: the run decides (it lets the files in hand finish).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from smplcore.motion.models import resolve_backend

    if "torch" in sys.modules or resolve_backend(options.backend, options.vertices) == "torch":
        with contextlib.suppress(ImportError):
            import torch

            torch.set_num_threads(threads)
    _STATE = WorkerState.build(options)


def _worker_run(task: Task) -> dict[str, Any]:
    assert _STATE is not None, "worker not initialised"
    return process_file(task, _STATE)


def _ray_run(options: ProcessOptions, task: Task) -> dict[str, Any]:
    """A Ray task: the same function, with the worker's models kept between tasks."""
    key = json.dumps(asdict(options), sort_keys=True)
    state = _RAY_STATES.get(key)
    if state is None:
        with contextlib.suppress(ImportError):
            import torch

            torch.set_num_threads(1)
        state = _RAY_STATES[key] = WorkerState.build(options)
    return process_file(task, state)


@contextlib.contextmanager
def _single_threaded_blas():
    """One BLAS / OpenMP thread in the workers started meanwhile (they read these when they start; the fork
    server keeps what it saw first, so this is the one setting that holds for every run). Torch's thread
    count is set in each worker at run time instead."""
    saved = {k: os.environ.get(k) for k in _THREAD_VARS}
    os.environ.update({k: "1" for k in _THREAD_VARS})
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def available_cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _run_inline(tasks: list[Task], options: ProcessOptions, on_result: Callable, tick: Callable) -> None:
    state = WorkerState.build(options)
    for task in tasks:
        on_result(process_file(task, state))
        tick()


def _mp_context(options: ProcessOptions) -> Any:
    """A fork server where there is one (workers fork from a process that has imported NumPy, smplcore
    and torch once: fast start, no threads forked), else spawn. Never plain fork (threads in the parent)."""
    import multiprocessing

    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    context = multiprocessing.get_context("forkserver")
    preload = ["numpy", "smplcore.motion.process", "smplcore.motion.models", "smplcore.model_setup"]
    from smplcore.motion.models import resolve_backend

    if resolve_backend(options.backend, options.vertices) == "torch":
        preload.append("torch")
    context.set_forkserver_preload(preload)
    return context


def _run_pool(tasks: list[Task], options: ProcessOptions, workers: int, on_result: Callable, tick: Callable) -> None:
    threads = max(1, available_cpus() // workers)
    context = _mp_context(options)
    attempts: dict[str, int] = {}
    pending = list(tasks)
    alive_r, alive_w = context.Pipe(duplex=False)  # the workers' lifeline (see _watch_parent)
    try:
        _pool_rounds(pending, options, workers, threads, context, alive_r, attempts, on_result, tick)
    finally:
        alive_w.close()
        alive_r.close()


def _pool_rounds(
    pending: list[Task],
    options: ProcessOptions,
    workers: int,
    threads: int,
    context: Any,
    alive: Any,
    attempts: dict[str, int],
    on_result: Callable,
    tick: Callable,
) -> None:
    while pending:
        broken: list[Task] = []
        with (
            _single_threaded_blas(),
            ProcessPoolExecutor(
                max_workers=min(workers, len(pending)),
                mp_context=context,
                initializer=_init_worker,
                initargs=(options, threads, alive),
            ) as pool,
        ):
            futures = {pool.submit(_worker_run, task): task for task in pending}
            try:
                while futures:
                    done, _ = wait(list(futures), timeout=1.0, return_when=FIRST_COMPLETED)
                    for future in done:
                        task = futures.pop(future)
                        try:
                            on_result(future.result())
                        except BrokenProcessPool:
                            broken.append(task)
                    tick()
            except BaseException:
                for future in futures:
                    future.cancel()
                raise
        pending = []
        for task in broken:  # a worker died (killed, out of memory): retry its files once
            attempts[task.source] = attempts.get(task.source, 0) + 1
            if attempts[task.source] < 2:
                pending.append(task)
            else:
                on_result(
                    {
                        "input": task.relative,
                        "output": None,
                        "status": "skipped",
                        "seconds": 0.0,
                        "reason": "the worker process died while processing this file (out of memory?)",
                    }
                )


def _run_ray(
    tasks: list[Task],
    options: ProcessOptions,
    address: str,
    workers: int | None,
    on_result: Callable,
    tick: Callable,
) -> int:
    """Run the tasks on Ray; returns the number of CPUs of the cluster."""
    try:
        import ray
    except ImportError:
        raise ProcessError("--ray needs Ray, an optional dependency: pip install 'ray'") from None
    started = False
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
        if address in ("", "local", None):
            if workers:
                kwargs["num_cpus"] = workers
        else:
            kwargs["address"] = address
        ray.init(**kwargs)
        started = True
    pending: dict[Any, Task] = {}
    try:
        cpus = int(ray.cluster_resources().get("CPU", 0))
        remote = ray.remote(num_cpus=1, max_retries=1)(_ray_run)
        options_ref = ray.put(options)
        pending = {remote.remote(options_ref, task): task for task in tasks}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=len(pending), timeout=0.5)
            for ref in done:
                task = pending.pop(ref)
                try:
                    result = ray.get(ref)
                except Exception as exc:  # noqa: BLE001 -- a failed task is one skipped file
                    result = {
                        "input": task.relative,
                        "output": None,
                        "status": "skipped",
                        "seconds": 0.0,
                        "reason": f"Ray task failed: {type(exc).__name__}: {exc}",
                    }
                on_result(result)
            tick()
    except BaseException:
        for ref in pending:  # interrupted: drop the queued tasks (running ones write atomically)
            with contextlib.suppress(Exception):
                ray.cancel(ref)
        raise
    finally:
        if started:
            ray.shutdown()
    return cpus


# --------------------------------------------------------------------------------------------------
# The job


@dataclass
class Summary:
    """What a run did. ``exit_code`` is 1 when any file was skipped, else 0."""

    input: Path
    output: Path
    files: int = 0
    done: int = 0
    existing: int = 0
    skipped: list[tuple[str, str]] = field(default_factory=list)
    frames: int = 0
    source_frames: int = 0
    seconds: float = 0.0
    workers: int = 0
    executor: str = "processes"
    manifest: Path | None = None

    @property
    def frames_per_second(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else 0.0

    @property
    def exit_code(self) -> int:
        return 1 if self.skipped else 0

    def format(self) -> str:
        lines = [
            f"{self.files} files: {self.done} processed, {self.existing} already done, {len(self.skipped)} skipped",
            f"{self.frames:,} frames (from {self.source_frames:,} source frames) in {self.seconds:.1f} s: "
            f"{self.frames_per_second:,.0f} frames/s "
            + ("in this process" if self.workers == 0 else f"with {self.workers} {self.executor}"),
            f"outputs in {self.output}; manifest {self.manifest}",
        ]
        if self.skipped:
            lines.append("skipped:")
            lines += [f"  {path}: {reason}" for path, reason in self.skipped]
        return "\n".join(lines)


def find_inputs(
    input_dir: Path, output_dir: Path, options: ProcessOptions, exclude: Iterable[str] = DEFAULT_EXCLUDE
) -> list[Task]:
    """The sequences under ``input_dir`` (``*.npz``, minus ``exclude`` patterns), largest first."""
    input_dir, output_dir = Path(input_dir), Path(output_dir)
    patterns = list(exclude)
    if input_dir.is_file():
        files = [(input_dir, Path(input_dir.name))]
    else:
        files = []
        out_resolved = output_dir.resolve()
        for root, dirs, names in os.walk(input_dir, followlinks=True):
            root_path = Path(root)
            dirs[:] = sorted(d for d in dirs if (root_path / d).resolve() != out_resolved)
            for name in sorted(names):
                if not name.lower().endswith(".npz") or name.startswith("."):
                    continue
                rel = (root_path / name).relative_to(input_dir)
                if any(fnmatch.fnmatch(name, p) or fnmatch.fnmatch(str(rel), p) for p in patterns):
                    continue
                files.append((root_path / name, rel))
    tasks = []
    for path, rel in files:
        try:
            size = path.stat().st_size
        except OSError:
            size = 0
        tasks.append(Task(str(path.resolve()), rel.as_posix(), str(output_dir / rel.with_suffix(options.suffix)), size))
    tasks.sort(key=lambda t: (-t.size, t.relative))
    return tasks


def _npy_shape(fh: Any) -> tuple[int, ...]:
    version = np.lib.format.read_magic(fh)
    read = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
    return tuple(read[version](fh)[0])


def _output_frames(path: Path) -> int | None:
    """Number of frames in an existing output, read from its header (None if unreadable)."""
    import zipfile

    try:
        if path.suffix == ".npy":
            with open(path, "rb") as fh:
                return int(_npy_shape(fh)[0])
        with zipfile.ZipFile(path) as archive, archive.open("joints.npy") as fh:
            return int(_npy_shape(fh)[0])
    except Exception:  # noqa: BLE001 -- unreadable: not a finished output
        return None


def _clean_temporaries(output_dir: Path) -> int:
    removed = 0
    for root, _, names in os.walk(output_dir):
        for name in names:
            if name.startswith(".") and name.endswith(TMP_SUFFIX):
                with contextlib.suppress(OSError):
                    os.unlink(os.path.join(root, name))
                    removed += 1
    return removed


@contextlib.contextmanager
def _locked(output_dir: Path):
    """Hold the output folder's lock (released by the OS if the process dies)."""
    path = output_dir / LOCK_NAME
    fh = open(path, "a+")
    try:
        try:
            import fcntl
        except ImportError:  # Windows: no lock
            fcntl = None
        if fcntl is not None:
            try:
                fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                raise ProcessError(
                    f"{output_dir}: another 'smplcore process' run is writing to this folder (lock {path})"
                ) from None
        fh.seek(0)
        fh.truncate()
        fh.write(f"{os.getpid()}\n")
        fh.flush()
        yield
    finally:
        fh.close()


class _Manifest:
    """The manifest (JSON), rewritten atomically at the start, every few seconds and at the end."""

    def __init__(self, path: Path, header: dict[str, Any]) -> None:
        self.path = path
        self.header = header
        self.entries: dict[str, dict[str, Any]] = {}
        self.last_write = 0.0

    @staticmethod
    def read(path: Path) -> dict[str, Any] | None:
        try:
            with open(path, encoding="utf-8") as fh:
                return json.load(fh)
        except (OSError, ValueError):
            return None

    def write(self, status: str, totals: dict[str, Any]) -> None:
        doc = dict(
            self.header,
            status=status,
            updated=_now(),
            totals=totals,
            files=[self.entries[k] for k in sorted(self.entries)],
        )
        text = json.dumps(doc, indent=1)
        atomic_write(self.path, lambda fh: fh.write(text.encode("utf-8")))
        self.last_write = time.monotonic()


class _Progress:
    """A tqdm bar of files with frames and frames/s (plain lines without tqdm; nothing when quiet)."""

    def __init__(self, total: int, enabled: bool) -> None:
        self.bar = None
        self.enabled = enabled
        self.start = time.perf_counter()
        self.last_line = 0.0
        if enabled:
            try:
                from tqdm import tqdm

                self.bar = tqdm(total=total, unit="file", desc="process", dynamic_ncols=True, file=sys.stderr)
            except ImportError:
                pass
        self.total = total
        self.count = 0

    def update(self, frames: int, files: int = 1) -> None:
        self.count += files
        elapsed = max(time.perf_counter() - self.start, 1e-9)
        if self.bar is not None:
            self.bar.set_postfix_str(f"{frames:,} frames, {frames / elapsed:,.0f} frames/s", refresh=False)
            self.bar.update(files)
        elif self.enabled and (time.monotonic() - self.last_line > 5 or self.count == self.total):
            self.last_line = time.monotonic()
            print(
                f"process: {self.count}/{self.total} files, {frames:,} frames, {frames / elapsed:,.0f} frames/s",
                file=sys.stderr,
                flush=True,
            )

    def write(self, text: str) -> None:
        if self.bar is not None:
            self.bar.write(text, file=sys.stderr)
        else:
            print(text, file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def process_tree(
    input_dir: str | Path,
    output_dir: str | Path,
    options: ProcessOptions | None = None,
    *,
    workers: int | None = None,
    ray_address: str | None = None,
    overwrite: bool = False,
    exclude: Iterable[str] = DEFAULT_EXCLUDE,
    progress: bool = True,
    manifest_interval: float = 5.0,
) -> Summary:
    """Process every sequence under ``input_dir`` into ``output_dir`` (see the module docstring).

    Parameters
    ----------
    input_dir : folder of AMASS-style ``.npz`` files (searched recursively), or one file.
    output_dir : where outputs go, mirroring ``input_dir``'s tree (``a/b.npz`` → ``a/b.npz`` or
        ``a/b.npy``), with ``manifest.json``.
    options : what to compute and store.
    workers : processes (None: every CPU; 0: in this process). With Ray: CPUs of the local cluster.
    ray_address : run on Ray: ``"local"`` (or ``""``) starts a local cluster (or uses the one this
        process already started), anything else is passed to ``ray.init(address=...)``.
    overwrite : recompute outputs that exist (also allowed with different settings).
    exclude : file-name or relative-path glob patterns to leave out.
    progress : show a progress bar and report skipped files on stderr.

    Returns
    -------
    Summary (also recorded in ``output_dir/manifest.json``).
    """
    options = options or ProcessOptions()
    input_dir, output_dir = Path(input_dir).expanduser(), Path(output_dir).expanduser()
    if not input_dir.exists():
        raise ProcessError(f"{input_dir}: no such file or folder")
    if input_dir.resolve() == output_dir.resolve():
        raise ProcessError(f"{output_dir}: the output folder must differ from the input folder")
    if options.model_path is not None and not Path(options.model_path).exists():
        raise ProcessError(f"{options.model_path}: no such model file or folder")
    if options.model_path is None and options.model_type not in (None, "open"):
        raise ProcessError(
            f"model_type {options.model_type!r} needs a model file or folder (--model-path); "
            "without one, the packaged open model is used (model_type 'open')"
        )
    output_dir.mkdir(parents=True, exist_ok=True)
    executor = "Ray CPUs" if ray_address is not None else "processes"
    if workers is None:
        workers = available_cpus() if ray_address is None else None
    elif workers < 0:
        raise ValueError(f"workers: expected 0 or more, got {workers}")

    with _locked(output_dir):
        _clean_temporaries(output_dir)
        manifest_path = output_dir / MANIFEST_NAME
        previous = _Manifest.read(manifest_path)
        settings = options.output_settings()
        if previous is not None and previous.get("settings") != settings and not overwrite:
            old = previous.get("settings") or {}
            diff = {k: (old.get(k), v) for k, v in settings.items() if old.get(k) != v}
            raise ProcessError(
                f"{output_dir} holds outputs made with other settings ({diff}: old, new); pass "
                "overwrite=True (--overwrite) to redo them, or write to another folder"
            )
        old_entries = {e.get("input"): e for e in (previous or {}).get("files", []) if isinstance(e, dict)}

        tasks = find_inputs(input_dir, output_dir, options, exclude)
        import smplcore

        manifest = _Manifest(
            manifest_path,
            {
                "tool": "smplcore process",
                "version": smplcore.__version__,
                "input": str(input_dir.resolve()),
                "output": str(output_dir.resolve()),
                "settings": settings,
                "started": _now(),
            },
        )
        summary = Summary(
            input_dir,
            output_dir,
            files=len(tasks),
            workers=workers or 0,
            executor=executor,
            manifest=manifest_path,
        )
        todo = []
        for task in tasks:
            out = Path(task.output)
            frames = None if overwrite or not out.exists() else _output_frames(out)
            if frames is None:
                todo.append(task)
                continue
            old = old_entries.get(task.relative) or {}
            entry = {k: v for k, v in old.items() if k not in ("status", "reason")}
            entry.update(input=task.relative, output=_relative_output(task), status="exists", frames=frames)
            manifest.entries[task.relative] = entry
            summary.existing += 1

        start = time.perf_counter()
        bar = _Progress(len(tasks), progress)
        if summary.existing:
            bar.update(0, summary.existing)

        def totals() -> dict[str, Any]:
            seconds = time.perf_counter() - start
            return {
                "files": summary.files,
                "done": summary.done,
                "exists": summary.existing,
                "skipped": len(summary.skipped),
                "frames": summary.frames,
                "source_frames": summary.source_frames,
                "seconds": round(seconds, 3),
                "frames_per_second": round(summary.frames / seconds, 1) if seconds > 0 else 0.0,
            }

        def on_result(entry: dict[str, Any]) -> None:
            manifest.entries[entry["input"]] = entry
            if entry["status"] == "done":
                summary.done += 1
                summary.frames += entry.get("frames", 0)
                summary.source_frames += entry.get("source_frames", 0)
            else:
                summary.skipped.append((entry["input"], entry.get("reason", "unknown")))
                bar.write(
                    f"skipped {input_dir / entry['input'] if input_dir.is_dir() else input_dir}: {entry.get('reason')}"
                )
            bar.update(summary.frames)

        def tick() -> None:
            if time.monotonic() - manifest.last_write >= manifest_interval:
                manifest.write("running", totals())

        manifest.write("running", totals())
        status = "interrupted"
        try:
            if not todo:
                pass
            elif ray_address is not None:
                summary.workers = _run_ray(todo, options, ray_address, workers, on_result, tick)
            elif workers == 0:
                _run_inline(todo, options, on_result, tick)
            else:
                _run_pool(todo, options, min(workers, len(todo)), on_result, tick)
            status = "finished"
        finally:
            bar.close()
            summary.seconds = time.perf_counter() - start
            manifest.write(status, totals())
    summary.skipped.sort()
    return summary
