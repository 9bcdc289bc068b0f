"""What batch jobs share (``smplcore process``, ``smplcore fit``): atomic output files, disk-full handling, and
the executors (:mod:`smplcore.jobs.executors`: in this process, in worker processes with a lifeline, or as Ray
tasks). The output-folder lock and the manifest format of ``smplcore process`` stay in
:mod:`smplcore.motion.process` (``smplcore fit`` writes its own manifest)."""

from smplcore.jobs.executors import (
    Job,
    available_cpus,
    remove_orphan_temporaries,
    run_inline,
    run_pool,
    run_ray,
    shut_down,
    single_threaded_blas,
    worker_context,
)
from smplcore.jobs.files import DISK_FULL_ERRNOS, TMP_SUFFIX, atomic_write, is_disk_full

__all__ = [
    "DISK_FULL_ERRNOS",
    "TMP_SUFFIX",
    "Job",
    "atomic_write",
    "available_cpus",
    "is_disk_full",
    "remove_orphan_temporaries",
    "run_inline",
    "run_pool",
    "run_ray",
    "shut_down",
    "single_threaded_blas",
    "worker_context",
]
