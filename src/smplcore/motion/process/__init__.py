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
  settings are kept in the manifest (a run that wrote no output does not pin them).
* **Never aborts on bad data.** A truncated, inconsistent or NaN-holding input (or one whose
  gendered model is missing) is reported with its path and reason, counted, recorded in the
  manifest and skipped; the summary's ``exit_code`` is 1 when anything was skipped, and
  :func:`process_tree` raises :class:`ProcessFailed` unless ``check=False``.
* **Stops cleanly on a full disk.** ENOSPC, EDQUOT or EFBIG while writing: no new file starts,
  finished outputs stay, the rest are ``not_done`` in a valid final manifest (room for it is
  reserved at the start), ``exit_code`` is :data:`EXIT_DISK_FULL` (3); a rerun resumes. A disk
  full at the start raises :class:`DiskFullError` (one line).
* **One writer.** A lock file in the output folder (removed at the end) stops two runs from
  writing the same tree.
* **Scripts.** A pool run started at the top level of a main script without
  ``if __name__ == "__main__":`` is refused before any worker starts (workers import the script).

Parallelism: ``workers`` processes (forked from a fork server, or spawned; one BLAS/OpenMP thread
each, torch threads = CPUs / workers), each keeping one loaded model per (model type, gender) and
evaluating frames in chunks; files are handed out largest first. ``ray_address`` runs the same
per-file function as Ray tasks (on a cluster the input and output folders must be on a file
system every node sees).
"""

from __future__ import annotations

from smplcore.motion.process.manifest import LOCK_NAME, MANIFEST_NAME
from smplcore.motion.process.options import (
    DEFAULT_EXCLUDE,
    RECIPES,
    ProcessError,
    ProcessOptions,
    options_from_recipe,
    parse_axes,
)
from smplcore.motion.process.preflight import OutputSizeWarning
from smplcore.motion.process.report import EXIT_DISK_FULL, DiskFullError, ProcessFailed, Summary
from smplcore.motion.process.run import process_tree
from smplcore.motion.process.task import TMP_SUFFIX, Task, WorkerState, atomic_write, find_inputs, process_file

__all__ = [
    "DEFAULT_EXCLUDE",
    "EXIT_DISK_FULL",
    "LOCK_NAME",
    "MANIFEST_NAME",
    "RECIPES",
    "DiskFullError",
    "OutputSizeWarning",
    "ProcessFailed",
    "TMP_SUFFIX",
    "ProcessError",
    "ProcessOptions",
    "Summary",
    "Task",
    "WorkerState",
    "atomic_write",
    "find_inputs",
    "options_from_recipe",
    "parse_axes",
    "process_file",
    "process_tree",
]
