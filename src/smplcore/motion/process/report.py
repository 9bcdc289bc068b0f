"""What a run reports: its :class:`Summary`, its progress bar, and the errors that end it."""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from smplcore.motion.process.options import ProcessError

EXIT_DISK_FULL = 3  # exit status of `smplcore process` when the disk filled up (0 done, 1 skipped, 2 usage)


class DiskFullError(ProcessError):
    """The output folder's disk (or quota, or file-size limit) has no room: the run cannot start."""


class ProcessFailed(RuntimeError):
    """Raised by :func:`~smplcore.motion.process_tree` (``check=True``) when files were skipped or the disk
    filled up; ``summary`` is the run's :class:`Summary` (the manifest is written)."""

    def __init__(self, summary: Summary) -> None:
        super().__init__(summary.format())
        self.summary = summary


@dataclass
class Summary:
    """What a run did.

    ``exit_code``: 0 when every file is done, 1 when any file was skipped (bad data), 3 when the run
    stopped because the disk was full (``stopped`` says why; ``not_done`` files are left for a rerun).
    """

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
    not_done: int = 0
    stopped: str | None = None
    open_model_betas: list[str] = field(default_factory=list)  # motion types whose betas drove the open model

    @property
    def frames_per_second(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else 0.0

    @property
    def exit_code(self) -> int:
        if self.stopped:
            return EXIT_DISK_FULL
        return 1 if self.skipped else 0

    @property
    def ok(self) -> bool:
        """Whether every file is done (nothing skipped, nothing left)."""
        return self.exit_code == 0

    def format(self) -> str:
        lines = [
            f"{self.files} files: {self.done} processed, {self.existing} already done, {len(self.skipped)} skipped"
            + (f", {self.not_done} not done" if self.not_done else ""),
            f"{self.frames:,} frames (from {self.source_frames:,} source frames) in {self.seconds:.1f} s: "
            f"{self.frames_per_second:,.0f} frames/s "
            + ("in this process" if self.workers == 0 else f"with {self.workers} {self.executor}"),
            f"outputs in {self.output}; manifest {self.manifest}",
        ]
        if self.skipped:
            lines.append("skipped:")
            lines += [f"  {path}: {reason}" for path, reason in self.skipped]
        if self.stopped:
            lines.append(f"stopped: {self.stopped}; free some space and rerun to resume")
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
