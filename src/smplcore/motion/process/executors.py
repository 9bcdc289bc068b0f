"""Where the files run: in this process, in a pool of worker processes, or as Ray tasks."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import sys
import threading
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict
from typing import Any

from smplcore.motion.process.options import ProcessError, ProcessOptions
from smplcore.motion.process.task import Task, WorkerState, process_file

_THREAD_VARS = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)


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


def _run_inline(
    tasks: list[Task], options: ProcessOptions, on_result: Callable, tick: Callable, stopping: Callable
) -> None:
    state = WorkerState.build(options)
    for task in tasks:
        if stopping():
            return
        on_result(process_file(task, state))
        tick()


def _mp_context(options: ProcessOptions) -> Any:
    """A fork server where there is one (workers fork from a process that has imported NumPy, smplcore
    and torch once: fast start, no threads forked), else spawn. Never plain fork (threads in the parent)."""
    import multiprocessing

    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    context = multiprocessing.get_context("forkserver")
    preload = ["numpy", "smplcore.motion.process", "smplcore.motion.models", "smplcore.frontend"]
    from smplcore.motion.models import resolve_backend

    if resolve_backend(options.backend, options.vertices) == "torch":
        preload.append("torch")
    context.set_forkserver_preload(preload)
    return context


def _run_pool(
    tasks: list[Task], options: ProcessOptions, workers: int, on_result: Callable, tick: Callable, stopping: Callable
) -> None:
    """Run the tasks in worker processes. ``stopping()`` true (a full disk): no new file starts, the files in
    hand finish. Any exception here (Ctrl-C) cuts the workers' lifeline first, so they exit at once (their
    outputs are atomic; a half-written temporary is removed by the next run) instead of finishing their files."""
    threads = max(1, available_cpus() // workers)
    context = _mp_context(options)
    attempts: dict[str, int] = {}
    pending = list(tasks)
    alive_r, alive_w = context.Pipe(duplex=False)  # the workers' lifeline (see _watch_parent)
    try:
        _pool_rounds(
            pending, options, workers, threads, context, (alive_r, alive_w), attempts, on_result, tick, stopping
        )
    finally:
        alive_w.close()
        alive_r.close()


WORKER_DIED = (
    "the worker process died while processing this file (out of memory? killed?); if every file says "
    "this, a worker could not start: see the errors printed above"
)


def _pool_rounds(
    pending: list[Task],
    options: ProcessOptions,
    workers: int,
    threads: int,
    context: Any,
    lifeline: tuple[Any, Any],
    attempts: dict[str, int],
    on_result: Callable,
    tick: Callable,
    stopping: Callable,
) -> None:
    alive, alive_w = lifeline
    while pending and not stopping():
        broken: list[Task] = []
        with _single_threaded_blas():
            pool = ProcessPoolExecutor(
                max_workers=min(workers, len(pending)),
                mp_context=context,
                initializer=_init_worker,
                initargs=(options, threads, alive),
            )
            try:
                futures: dict[Any, Task] = {}
                for k, task in enumerate(pending):
                    try:
                        futures[pool.submit(_worker_run, task)] = task
                    except (BrokenProcessPool, OSError):  # the workers died while the files were handed out
                        broken.extend(pending[k:])
                        break
                while futures:
                    done, _ = wait(list(futures), timeout=0.5, return_when=FIRST_COMPLETED)
                    for future in done:
                        task = futures.pop(future)
                        try:
                            on_result(future.result())
                        except BrokenProcessPool:
                            broken.append(task)
                    if stopping():  # drop the queued files; the running ones finish
                        for future in [f for f in futures if f.cancel()]:
                            futures.pop(future)
                    tick()
            except BaseException:
                # The workers exit now (see _watch_parent), which breaks the pool: its manager thread then fails
                # every pending future itself. Cancelling them first made it raise InvalidStateError: CANCELLED
                # from its thread (Python 3.11) before the clean message of a Ctrl-C.
                alive_w.close()
                raise
            finally:
                shut_down(pool)
        pending = []
        for task in broken:  # a worker died (killed, out of memory): retry its files once
            attempts[task.source] = attempts.get(task.source, 0) + 1
            if attempts[task.source] < 2:
                pending.append(task)
            else:
                on_result(
                    {"input": task.relative, "output": None, "status": "skipped", "seconds": 0.0, "reason": WORKER_DIED}
                )


def shut_down(pool: Any) -> None:
    """``pool.shutdown(wait=True)``, past a race of CPython 3.11 (gh-125451, bpo-39995): the manager thread of a
    broken pool closes the wakeup pipe that ``shutdown`` writes to, which then raises ``OSError('handle is
    closed')`` instead of waiting. The pipe is closed by then, so a second call passes it and joins the thread."""
    try:
        pool.shutdown(wait=True)
    except OSError as exc:
        if "handle is closed" not in str(exc):
            raise
        pool.shutdown(wait=True)


def _run_ray(
    tasks: list[Task],
    options: ProcessOptions,
    address: str,
    workers: int | None,
    on_result: Callable,
    tick: Callable,
    stopping: Callable,
) -> int:
    """Run the tasks on Ray; returns the number of CPUs of the cluster."""
    try:
        import ray
    except ImportError:
        raise ProcessError(
            '--ray needs Ray, which is not installed; install it with: pip install "smplcore[ray]"'
        ) from None
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
            if stopping():  # drop the queued tasks; a running one finishes or is cancelled
                for ref in pending:
                    with contextlib.suppress(Exception):
                        ray.cancel(ref)
                pending = {}
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
