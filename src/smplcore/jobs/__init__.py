"""What batch jobs share (``smplcore process``, ``smplcore fit``): atomic output files and disk-full handling.

The lock, manifest, executors and progress of a run are still in :mod:`smplcore.motion.process` (issue 24 moves
them here)."""

from smplcore.jobs.files import DISK_FULL_ERRNOS, TMP_SUFFIX, atomic_write, is_disk_full

__all__ = ["DISK_FULL_ERRNOS", "TMP_SUFFIX", "atomic_write", "is_disk_full"]
