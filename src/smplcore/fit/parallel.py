"""Independent bodies solved on several cores: chunks of the batch in threads.

The solver's work is NumPy on arrays of a few hundred kilobytes, which releases the GIL, with a BLAS held
to one thread (:func:`smplcore.fit.result.single_threaded_blas`); chunks of bodies in threads use the
other cores without pickling anything. Bodies that share coefficients are one problem and stay together.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

import numpy as np

T = TypeVar("T")

# Fewer bodies than this per thread are not worth a thread.
_MIN_BODIES = 16


def available_cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def chunks(batch: int, workers: int | None) -> list[np.ndarray]:
    """Consecutive row ranges of ``batch`` bodies, one per thread (``workers``: None for every core)."""
    wanted = available_cores() if workers is None else max(1, int(workers))
    count = max(1, min(wanted, batch // _MIN_BODIES))
    return [rows for rows in np.array_split(np.arange(batch), count) if len(rows)]


def map_chunks(fn: Callable[[np.ndarray], T], parts: list[np.ndarray], workers: int | None = None) -> list[T]:
    """``[fn(rows) for rows in parts]``, in up to ``workers`` threads (None: one per part, at most the cores)."""
    threads = min(len(parts), available_cores() if workers is None else max(1, int(workers)))
    if threads <= 1:
        return [fn(rows) for rows in parts]
    with ThreadPoolExecutor(max_workers=threads) as pool:
        return list(pool.map(fn, parts))
