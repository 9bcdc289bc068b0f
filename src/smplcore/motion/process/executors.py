"""Where ``smplcore process`` runs its files: the shared executors of :mod:`smplcore.jobs.executors` (in this
process, in worker processes, or as Ray tasks), with the motion pipeline's worker state: each worker builds
the run's models once (:class:`~smplcore.motion.process.task.WorkerState`)."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable
from typing import Any

from smplcore.jobs import Job, available_cpus, run_inline, run_pool, run_ray, worker_context
from smplcore.motion.process.options import ProcessOptions
from smplcore.motion.process.task import Task, WorkerState, process_file

__all__ = ["available_cpus", "run_files"]

_STATE: WorkerState | None = None

WORKER_DIED = (
    "the worker process died while processing this file (out of memory? killed?); if every file says "
    "this, a worker could not start: see the errors printed above"
)


def _setup(options: ProcessOptions, threads: int | None) -> None:
    """A worker's models, built once; torch at ``threads`` threads (None: as it is, in the run's own process)."""
    global _STATE
    from smplcore.motion.models import resolve_backend

    if threads is not None and (
        "torch" in sys.modules or resolve_backend(options.backend, options.vertices) == "torch"
    ):
        with contextlib.suppress(ImportError):
            import torch

            torch.set_num_threads(threads)
    _STATE = WorkerState.build(options)


def _work(task: Task) -> dict[str, Any]:
    assert _STATE is not None, "worker not initialised"
    return process_file(task, _STATE)


def _dead(task: Task, reason: str) -> dict[str, Any]:
    return {
        "input": task.relative,
        "output": None,
        "status": "skipped",
        "seconds": 0.0,
        "reason": WORKER_DIED if reason == "died" else reason,
    }


def _preload(options: ProcessOptions) -> list[str]:
    """What the fork server imports once for the workers."""
    from smplcore.motion.models import resolve_backend

    preload = ["numpy", "smplcore.motion.process", "smplcore.motion.models", "smplcore.frontend"]
    return [*preload, "torch"] if resolve_backend(options.backend, options.vertices) == "torch" else preload


def run_files(
    tasks: list[Task],
    options: ProcessOptions,
    workers: int | None,
    ray_address: str | None,
    on_result: Callable,
    tick: Callable,
    stopping: Callable,
) -> int | None:
    """Process ``tasks``: as Ray tasks with ``ray_address`` (returns the cluster's CPU count), in this process
    with ``workers`` 0, else in ``workers`` processes (torch sharing the CPUs among them)."""
    if ray_address is not None:
        job = Job(_work, _dead, _setup, (options, 1))
        return run_ray(tasks, job, ray_address, workers, on_result, tick, stopping)
    if workers == 0:
        run_inline(tasks, Job(_work, _dead, _setup, (options, None)), on_result, tick, stopping)
        return workers
    workers = min(workers or 1, len(tasks))
    job = Job(_work, _dead, _setup, (options, max(1, available_cpus() // workers)))
    run_pool(tasks, job, workers, on_result, tick, stopping, context=worker_context(_preload(options)))
    return workers
