"""One input file: the :class:`Task`, its atomic output write, and :func:`process_file` (what a worker runs)."""

from __future__ import annotations

import errno
import fnmatch
import os
import time
import warnings
from collections.abc import Iterable
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.jobs import DISK_FULL_ERRNOS, TMP_SUFFIX, atomic_write, is_disk_full  # noqa: F401 (re-exported)
from smplcore.motion.process.options import DEFAULT_EXCLUDE, ProcessOptions, _apply_axes

NOT_DONE = "not_done"  # manifest status of a file a stopped run did not finish (a rerun does it)


def disk_full_reason(exc: OSError, what: str) -> str:
    """One line: ``disk full writing <what>: No space left on device [errno ENOSPC]``."""
    name = errno.errorcode.get(exc.errno or 0, str(exc.errno))
    return f"disk full writing {what}: {exc.strerror or exc} [errno {name}]"


@dataclass(frozen=True)
class Task:
    """One input file: its absolute path, its path relative to the input root, its output."""

    source: str
    relative: str
    output: str
    size: int = 0


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


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
            dmpl_path=options.dmpl_path,
            skinning=options.skinning,
        )
        return cls(options, cache, Evaluator(chunk=options.chunk))


def process_file(task: Task, state: WorkerState) -> dict[str, Any]:
    """Process one sequence; never raises for bad data: returns a manifest entry.

    The entry's status is ``done``, ``skipped`` (bad data, with the ``reason``) or, when the output
    could not be written for lack of space (ENOSPC, EDQUOT, EFBIG), ``not_done`` with ``disk_full``
    set: the run stops there, and a rerun after freeing space does the file.
    """
    from smplcore.motion import resample as rs
    from smplcore.motion.models import pick_gender
    from smplcore.motion.sequence import ShapeSpaceWarning, load_motion

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
        layout = "smpl" if motion.model_type == "open" else motion.model_type  # an open-model fit: SMPL's layout
        model_type = options.model_type or (layout if options.model_path else "open")
        gender = pick_gender(motion.gender, options.gender)
        loaded = state.cache.get(model_type, gender)
        with warnings.catch_warnings():  # reported to the main process (which warns once) in the entry
            warnings.simplefilter("ignore", ShapeSpaceWarning)
            joints, verts = state.evaluator.run(
                motion, loaded, vertices=options.vertices, skeleton_only=not options.extra_joints
            )
        if loaded.model_type == "open" and motion.model_type != "open" and np.any(motion.betas[: loaded.num_betas]):
            entry["open_model_betas"] = motion.model_type
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
            atomic_write(Path(task.output), lambda fh: save(fh, **arrays))  # type: ignore[arg-type]
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
    except OSError as exc:
        if is_disk_full(exc):
            entry.update(status=NOT_DONE, disk_full=True, reason=disk_full_reason(exc, task.output))
        else:
            entry["reason"] = _reason(exc)
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
        # absolute, symlinks kept: messages name the path as typed, not a link's target
        source = os.path.abspath(path)
        tasks.append(Task(source, rel.as_posix(), str(output_dir / rel.with_suffix(options.suffix)), size))
    tasks.sort(key=lambda t: (-t.size, t.relative))
    return tasks
