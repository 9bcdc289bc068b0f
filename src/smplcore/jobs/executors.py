"""Where a batch job's items run: in this process, in a pool of worker processes, or as Ray tasks.

Shared by ``smplcore process`` (:mod:`smplcore.motion.process`) and ``smplcore fit`` (:mod:`smplcore.fit.cli`).
A :class:`Job` is a top-level function ``work(item) -> row`` (a manifest entry; it never raises for a bad item),
run after ``prepare(*prepare_args)`` in each worker (models are built there, once). Every executor reports each
row through ``on_result(row)`` and calls ``tick()`` after each; ``stopping()`` true (a full disk, a fatal
write error) starts no new item, while the items in hand finish.

Worker processes hold a lifeline: the read end of a pipe that only the run writes to. They exit when it reads
end-of-file, that is when the run dies or is interrupted (Ctrl-C), however it ended, so a killed run leaves no
workers behind; their outputs are atomic (:func:`smplcore.jobs.atomic_write`), and the temporaries of workers
that ended are removed by :func:`remove_orphan_temporaries`. An item whose worker died (killed, out of memory)
is retried once in a new pool, then reported through ``Job.dead``.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from smplcore.jobs.files import TMP_SUFFIX

Row = dict[str, Any]

_THREAD_VARS = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)


@dataclass(frozen=True)
class Job:
    """What a batch runs on each item.

    Attributes
    ----------
    work : ``work(item) -> row``, a top-level (picklable) function; returns the item's manifest entry.
    dead : ``dead(item, reason) -> row``, the entry of an item whose worker died or whose Ray task failed.
    prepare : run once in each worker before its first item (None: nothing), a top-level function.
    prepare_args : the arguments of ``prepare`` (picklable).
    """

    work: Callable[[Any], Row]
    dead: Callable[[Any, str], Row]
    prepare: Callable[..., None] | None = None
    prepare_args: tuple[Any, ...] = ()


def available_cpus() -> int:
    """The CPUs this process may run on (its affinity mask; the machine's count where there is none)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


@contextlib.contextmanager
def single_threaded_blas():
    """One BLAS / OpenMP thread in the workers started meanwhile (they read these variables when they start; a
    fork server keeps what it saw first, so this is the one setting that holds for every run)."""
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


def run_inline(items: Iterable[Any], job: Job, on_result: Callable, tick: Callable, stopping: Callable) -> None:
    """The items one after another in this process."""
    if job.prepare is not None:
        job.prepare(*job.prepare_args)
    for item in items:
        if stopping():
            return
        on_result(job.work(item))
        tick()


def _watch_parent(alive: Any) -> None:
    """Exit when the run's process dies or cuts the lifeline (end-of-file on ``alive``)."""
    try:
        alive.recv()
    except BaseException:  # noqa: BLE001 -- EOFError: the run is gone
        pass
    os._exit(3)


def _init_worker(job: Job, alive: Any) -> None:
    threading.Thread(target=_watch_parent, args=(alive,), daemon=True).start()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C goes to the process group: the run decides
    if job.prepare is not None:
        job.prepare(*job.prepare_args)


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


def worker_context(preload: list[str]) -> Any:
    """A fork server where there is one (workers fork from a process that has imported ``preload`` once: fast
    start, no threads forked), else spawn. Never plain fork: threads in the parent, and a forked worker would
    hold the write end of its own lifeline."""
    import multiprocessing

    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(preload)
    return context


def run_pool(
    items: list[Any],
    job: Job,
    workers: int,
    on_result: Callable,
    tick: Callable,
    stopping: Callable,
    context: Any = None,
) -> None:
    """The items in ``workers`` processes of the multiprocessing ``context`` (None: :func:`worker_context` with
    nothing preloaded), with one BLAS thread each. Any exception here (Ctrl-C) cuts the workers' lifeline first,
    so they exit at once."""
    context = context or worker_context([])
    alive_r, alive_w = context.Pipe(duplex=False)
    attempts: dict[int, int] = {}
    pending = list(enumerate(items))
    try:
        while pending and not stopping():
            broken = _pool_round(pending, job, workers, context, (alive_r, alive_w), on_result, tick, stopping)
            pending = []
            for index, item in broken:  # a worker died (killed, out of memory): retry its items once
                attempts[index] = attempts.get(index, 0) + 1
                if attempts[index] < 2:
                    pending.append((index, item))
                else:
                    on_result(job.dead(item, "died"))
    finally:
        alive_w.close()
        alive_r.close()


def _pool_round(
    pending: list[tuple[int, Any]],
    job: Job,
    workers: int,
    context: Any,
    lifeline: tuple[Any, Any],
    on_result: Callable,
    tick: Callable,
    stopping: Callable,
) -> list[tuple[int, Any]]:
    """One pool over ``pending``; returns the items whose worker died."""
    alive, alive_w = lifeline
    broken: list[tuple[int, Any]] = []
    with single_threaded_blas():
        pool = ProcessPoolExecutor(
            max_workers=min(workers, len(pending)), mp_context=context, initializer=_init_worker, initargs=(job, alive)
        )
        try:
            futures: dict[Any, tuple[int, Any]] = {}
            for k, entry in enumerate(pending):
                try:
                    futures[pool.submit(job.work, entry[1])] = entry
                except (BrokenProcessPool, OSError):  # the workers died while the items were handed out
                    broken.extend(pending[k:])
                    break
            while futures:
                done, _ = wait(list(futures), timeout=0.5, return_when=FIRST_COMPLETED)
                for future in done:
                    entry = futures.pop(future)
                    try:
                        on_result(future.result())
                    except BrokenProcessPool:
                        broken.append(entry)
                if stopping():  # drop the queued items; the running ones finish
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
    return broken


_RAY_PREPARED: set[str] = set()


def _ray_call(job: Job, item: Any) -> Row:
    """A Ray task: the job's ``prepare`` once per worker process (models kept between tasks), then the item."""
    key = repr((job.prepare, job.prepare_args))
    if job.prepare is not None and key not in _RAY_PREPARED:
        job.prepare(*job.prepare_args)
        _RAY_PREPARED.add(key)
    return job.work(item)


def run_ray(
    items: list[Any],
    job: Job,
    address: str | None,
    workers: int | None,
    on_result: Callable,
    tick: Callable,
    stopping: Callable,
) -> int:
    """The items as Ray tasks on the cluster at ``address`` ("" / "local" / None: a local one of ``workers``
    CPUs); returns the cluster's CPU count. A failed task is one row from ``job.dead``."""
    try:
        import ray
    except ImportError:
        from smplcore._deps import missing

        raise missing("ray", "--ray", "ray") from None
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
    pending: dict[Any, Any] = {}
    try:
        cpus = int(ray.cluster_resources().get("CPU", 0))
        remote = ray.remote(num_cpus=1, max_retries=1)(_ray_call)
        job_ref = ray.put(job)
        pending = {remote.remote(job_ref, item): item for item in items}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=len(pending), timeout=0.5)
            for ref in done:
                item = pending.pop(ref)
                try:
                    row = ray.get(ref)
                except Exception as exc:  # noqa: BLE001 -- a failed task is one skipped item
                    row = job.dead(item, f"Ray task failed: {type(exc).__name__}: {exc}")
                on_result(row)
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


def remove_orphan_temporaries(folders: Iterable[Path]) -> int:
    """Remove the temporaries of :func:`~smplcore.jobs.atomic_write` in ``folders`` whose writing process has
    ended (never renamed into place); returns how many. Temporaries of live processes are kept."""
    removed = 0
    for folder in folders:
        for tmp in Path(folder).glob(f".*{TMP_SUFFIX}"):
            pid = tmp.name[: -len(TMP_SUFFIX)].rpartition(".")[2].partition("-")[0]
            if not pid.isdigit() or _alive(int(pid)):
                continue
            with contextlib.suppress(OSError):
                tmp.unlink()
                removed += 1
    return removed


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    # a zombie (an ended worker not yet reaped) still answers: read its state where /proc has it
    with contextlib.suppress(OSError):
        return Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0] != "Z"
    return True
