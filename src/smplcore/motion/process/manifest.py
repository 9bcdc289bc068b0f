"""The output folder's bookkeeping: its lock, leftover temporaries, finished outputs, ``manifest.json``."""

from __future__ import annotations

import contextlib
import errno
import json
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.motion.process.options import ProcessError
from smplcore.motion.process.report import DiskFullError
from smplcore.motion.process.task import TMP_SUFFIX, _now, atomic_write, disk_full_reason, is_disk_full

MANIFEST_NAME = "manifest.json"
LOCK_NAME = ".smplcore-process.lock"


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
    """Hold the output folder's lock (released by the OS if the process dies); the lock file is removed
    when the run ends.

    The file is removed while still locked, so a run that opened it meanwhile holds a lock on a file
    that is gone: after locking, each run checks that the path is still the file it locked, and
    starts over if not.
    """
    fcntl: Any
    try:
        import fcntl
    except ImportError:  # Windows: no lock
        fcntl = None
    path = output_dir / LOCK_NAME
    while True:
        fh = _disk_full_is_fatal(lambda: open(path, "a+"), output_dir, "the lock file")
        if fcntl is None:
            break
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.seek(0)
            holder = fh.read().strip()
            fh.close()
            raise ProcessError(_locked_message(output_dir, path, holder)) from None
        try:
            same = os.path.samestat(os.fstat(fh.fileno()), os.stat(path))
        except FileNotFoundError:
            same = False
        if same:
            break
        fh.close()  # the run that held it removed it: lock the new one
    try:

        def write_pid() -> None:
            fh.seek(0)
            fh.truncate()
            fh.write(f"{os.getpid()}\n")
            fh.flush()

        _disk_full_is_fatal(write_pid, output_dir, "the lock file")
        yield
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)
        with contextlib.suppress(OSError):  # a pid that did not fit on a full disk is not written again
            fh.close()


def _disk_full_is_fatal(action: Callable[[], Any], output_dir: Path, what: str) -> Any:
    """``action()``, a disk-full error from it becoming a one-line :class:`DiskFullError`."""
    try:
        return action()
    except OSError as exc:
        if not is_disk_full(exc):
            raise
        raise DiskFullError(f"{output_dir}: {disk_full_reason(exc, what)}; free some space and rerun") from None


def _locked_message(output_dir: Path, path: Path, holder: str) -> str:
    if holder == str(os.getppid()):
        return (
            f"{output_dir}: locked by this process's parent (pid {holder}): this is a worker process of that run, "
            're-importing its main script, which calls process_tree outside `if __name__ == "__main__":`; '
            "put the call under that guard"
        )
    who = f" (pid {holder})" if holder.isdigit() else ""
    return f"{output_dir}: another 'smplcore process' run{who} is writing to this folder (lock {path})"


class SpaceReserve:
    """A file of ``size`` bytes kept in the output folder while a run writes, deleted when the disk fills
    so that the final manifest still fits; removed at the end of the run."""

    NAME = ".smplcore-process.reserve"

    def __init__(self, output_dir: Path, size: int) -> None:
        self.path = output_dir / self.NAME
        with open(self.path, "wb") as fh:
            try:
                os.posix_fallocate(fh.fileno(), 0, size)
            except (AttributeError, OSError) as exc:  # no fallocate (or not on this file system): write zeros
                if isinstance(exc, OSError) and exc.errno not in (None, errno.EOPNOTSUPP, errno.EINVAL):
                    raise
                fh.write(bytes(size))
            fh.flush()
            os.fsync(fh.fileno())

    def release(self) -> None:
        with contextlib.suppress(OSError):
            os.unlink(self.path)

    @staticmethod
    def size_for(files: int) -> int:
        """Room for a manifest of ``files`` entries (about 400 bytes each, written as a whole new copy)."""
        return 64 * 1024 + 1024 * files


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
