"""The job: :func:`process_tree` and its :class:`Summary`."""

from __future__ import annotations

import sys
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from smplcore.motion.process.executors import _run_inline, _run_pool, _run_ray, available_cpus
from smplcore.motion.process.manifest import MANIFEST_NAME, _clean_temporaries, _locked, _Manifest, _output_frames
from smplcore.motion.process.options import DEFAULT_EXCLUDE, ProcessError, ProcessOptions
from smplcore.motion.process.task import _now, _relative_output, find_inputs


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
