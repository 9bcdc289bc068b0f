"""The job: :func:`process_tree`."""

from __future__ import annotations

import contextlib
import shutil
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from smplcore.errors import warn
from smplcore.motion.process import preflight
from smplcore.motion.process.executors import available_cpus, run_files
from smplcore.motion.process.manifest import (
    MANIFEST_NAME,
    SpaceReserve,
    _clean_temporaries,
    _locked,
    _Manifest,
    _output_frames,
)
from smplcore.motion.process.options import DEFAULT_EXCLUDE, ProcessError, ProcessOptions
from smplcore.motion.process.report import DiskFullError, ProcessFailed, Summary, _Progress
from smplcore.motion.process.task import (
    NOT_DONE,
    Task,
    _now,
    _relative_output,
    disk_full_reason,
    find_inputs,
    is_disk_full,
)

DEFAULT_WARN_BYTES = 4e9  # warn before writing more than this


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
    check: bool = True,
    warn_bytes: float | None = DEFAULT_WARN_BYTES,
) -> Summary:
    """Process every sequence under ``input_dir`` into ``output_dir`` (see :mod:`smplcore.motion.process`).

    Parameters
    ----------
    input_dir : folder of AMASS-style ``.npz`` files (searched recursively), or one file.
    output_dir : where outputs go, mirroring ``input_dir``'s tree (``a/b.npz`` → ``a/b.npz`` or
        ``a/b.npy``), with ``manifest.json``.
    options : what to compute and store.
    workers : processes (None: every CPU; 0: in this process). With Ray: CPUs of the local cluster.
        Worker processes import the main script again: call ``process_tree`` under
        ``if __name__ == "__main__":`` (an unguarded call is refused with a ``ProcessError``).
    ray_address : run on Ray: ``"local"`` (or ``""``) starts a local cluster (or uses the one this
        process already started), anything else is passed to ``ray.init(address=...)``.
    overwrite : recompute outputs that exist (also allowed with different settings).
    exclude : file-name or relative-path glob patterns to leave out.
    progress : show a progress bar and report skipped files on stderr.
    manifest_interval : seconds between rewrites of the manifest during the run.
    check : raise :class:`ProcessFailed` (holding the summary) when any file was skipped or the disk
        filled up; False returns the summary whatever happened (look at ``summary.exit_code``).
    warn_bytes : warn (:class:`OutputSizeWarning`) before writing more than this many bytes; None: never.

    Returns
    -------
    Summary (also recorded in ``output_dir/manifest.json``).

    Raises
    ------
    ProcessError
        the job cannot start (bad folders or settings, a locked folder, an unguarded script).
    DiskFullError
        (a ProcessError) the output folder's disk is already full.
    ProcessFailed
        with ``check=True``, when files were skipped or the disk filled up during the run.
    """
    preflight.check_not_reimported()
    options = options or ProcessOptions()
    input_dir, output_dir = Path(input_dir).expanduser(), Path(output_dir).expanduser()
    if not input_dir.exists():
        raise ProcessError(f"{input_dir}: no such file or folder")
    if input_dir.resolve() == output_dir.resolve():
        raise ProcessError(f"{output_dir}: the output folder must differ from the input folder")
    if options.model_path is not None and not Path(options.model_path).exists():
        raise ProcessError(f"{options.model_path}: no such model file or folder")
    if options.dmpl_path is not None and not Path(options.dmpl_path).is_file():
        raise ProcessError(f"{options.dmpl_path}: no such DMPL file (dmpl_path / --dmpl)")
    if options.model_path is None and options.model_type not in (None, "open"):
        raise ProcessError(
            f"model_type {options.model_type!r} needs a model file or folder (--model-path); "
            "without one, the packaged open model is used (model_type 'open')"
        )
    if workers is not None and workers < 0:
        raise ValueError(f"workers: expected 0 or more, got {workers}")
    if workers is None:
        workers = available_cpus() if ray_address is None else None
    if ray_address is None and workers:
        preflight.check_main_guard()
    with _disk_full_at_start(output_dir, "the output folder"):
        output_dir.mkdir(parents=True, exist_ok=True)
    with _locked(output_dir):
        summary = _run_locked(input_dir, output_dir, options, workers, ray_address, overwrite, exclude, progress,
                              manifest_interval, warn_bytes)  # fmt: skip
    if summary.open_model_betas:
        from smplcore.motion.sequence import warn_open_model_betas

        warn_open_model_betas(summary.open_model_betas[0], stacklevel=2, key="process_tree")
    if check and summary.exit_code != 0:
        raise ProcessFailed(summary)
    return summary


@contextlib.contextmanager
def _disk_full_at_start(output_dir: Path, what: str):
    try:
        yield
    except OSError as exc:
        if not is_disk_full(exc):
            raise
        raise DiskFullError(f"{output_dir}: {disk_full_reason(exc, what)}; free some space and rerun") from None


def _holds_outputs(output_dir: Path, previous: dict[str, Any]) -> bool:
    """Whether the folder holds an output the previous run wrote (a run that skipped every file wrote none)."""
    for entry in previous.get("files", []):
        if isinstance(entry, dict) and entry.get("status") in ("done", "exists") and entry.get("output"):
            if (output_dir / str(entry["output"])).exists():
                return True
    return False


def _run_locked(
    input_dir: Path,
    output_dir: Path,
    options: ProcessOptions,
    workers: int | None,
    ray_address: str | None,
    overwrite: bool,
    exclude: Iterable[str],
    progress: bool,
    manifest_interval: float,
    warn_bytes: float | None,
) -> Summary:
    _clean_temporaries(output_dir)
    manifest_path = output_dir / MANIFEST_NAME
    previous = _Manifest.read(manifest_path)
    settings = options.output_settings()
    if previous is not None and previous.get("settings") != settings and not overwrite:
        if _holds_outputs(output_dir, previous):
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
    executor = "Ray CPUs" if ray_address is not None else "processes"
    summary = Summary(input_dir, output_dir, files=len(tasks), workers=workers or 0, executor=executor,
                      manifest=manifest_path)  # fmt: skip
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
    _warn_size(todo, options, output_dir, warn_bytes)

    start = time.perf_counter()

    def totals() -> dict[str, Any]:
        seconds = time.perf_counter() - start
        return {
            "files": summary.files,
            "done": summary.done,
            "exists": summary.existing,
            "skipped": len(summary.skipped),
            "not_done": summary.not_done,
            "frames": summary.frames,
            "source_frames": summary.source_frames,
            "seconds": round(seconds, 3),
            "frames_per_second": round(summary.frames / seconds, 1) if seconds > 0 else 0.0,
        }

    with _disk_full_at_start(output_dir, "the manifest"):
        reserve = SpaceReserve(output_dir, SpaceReserve.size_for(len(tasks)))
        try:
            manifest.write("running", totals())
        except BaseException:
            reserve.release()
            raise
    bar = _Progress(len(tasks), progress)
    if summary.existing:
        bar.update(0, summary.existing)

    def on_result(entry: dict[str, Any]) -> None:
        foreign = entry.pop("open_model_betas", None)
        if foreign and foreign not in summary.open_model_betas:
            summary.open_model_betas.append(foreign)
        manifest.entries[entry["input"]] = entry
        if entry["status"] == "done":
            summary.done += 1
            summary.frames += entry.get("frames", 0)
            summary.source_frames += entry.get("source_frames", 0)
        elif entry["status"] == NOT_DONE:
            summary.not_done += 1
            summary.stopped = summary.stopped or entry.get("reason", "disk full")
        else:
            summary.skipped.append((entry["input"], entry.get("reason", "unknown")))
            where = input_dir / entry["input"] if input_dir.is_dir() else input_dir
            bar.write(f"skipped {where}: {entry.get('reason')}")
        bar.update(summary.frames)

    def tick() -> None:
        if summary.stopped is None and time.monotonic() - manifest.last_write >= manifest_interval:
            try:
                manifest.write("running", totals())
            except OSError as exc:
                if not is_disk_full(exc):
                    raise
                summary.stopped = disk_full_reason(exc, str(manifest_path))

    status = "interrupted"
    try:
        if not todo:
            pass
        else:
            used = run_files(todo, options, workers, ray_address, on_result, tick, _stopping(summary))
            if ray_address is not None and used is not None:
                summary.workers = used
        status = "finished"
        if summary.stopped:
            status = "stopped"
            _mark_not_done(todo, manifest, summary)
    finally:
        bar.close()
        summary.seconds = time.perf_counter() - start
        if status != "finished":
            _clean_temporaries(output_dir)  # what killed workers left (a disk-full write removes its own)
        reserve.release()  # room for the last manifest, whatever happened
        _final_write(manifest, status, totals(), summary)
    summary.skipped.sort()
    return summary


def _stopping(summary: Summary):
    return lambda: summary.stopped is not None


def _mark_not_done(todo: list[Task], manifest: _Manifest, summary: Summary) -> None:
    for task in todo:
        if task.relative not in manifest.entries:
            manifest.entries[task.relative] = {
                "input": task.relative,
                "output": None,
                "status": NOT_DONE,
                "reason": "not started: the run stopped (disk full)",
            }
            summary.not_done += 1


def _final_write(manifest: _Manifest, status: str, totals: dict[str, Any], summary: Summary) -> None:
    try:
        manifest.write(status, totals)
    except OSError as exc:
        if not is_disk_full(exc):
            raise
        # The previous manifest stays as it was (valid JSON: writes are atomic).
        reason = disk_full_reason(exc, str(manifest.path)) + " (the manifest is the previous one)"
        summary.stopped = f"{summary.stopped}; {reason}" if summary.stopped else reason


def _warn_size(todo: list[Task], options: ProcessOptions, output_dir: Path, warn_bytes: float | None) -> None:
    if warn_bytes is None or not todo:
        return
    estimate = preflight.estimate_output_bytes(todo, options)
    if estimate <= warn_bytes:
        return
    try:
        free: int | None = shutil.disk_usage(output_dir).free
    except OSError:
        free = None
    warn(preflight.OutputSizeWarning(preflight.size_message(estimate, output_dir, len(todo), free)))
