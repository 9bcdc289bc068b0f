"""The pool's shutdown on CPython 3.11: a broken pool's manager thread closes the wakeup pipe that
``shutdown()`` writes to, so ``shutdown`` can raise ``OSError('handle is closed')`` (CPython gh-125451,
bpo-39995). A run must still end with its own summary, not with that OSError."""

from __future__ import annotations

import pytest

from smplcore.jobs import executors


class _RacingPool:
    """Stands in for a broken ProcessPoolExecutor whose first shutdown loses the race."""

    def __init__(self, error: BaseException | None) -> None:
        self.calls = 0
        self.error = error

    def shutdown(self, wait: bool = True) -> None:
        self.calls += 1
        if self.calls == 1 and self.error is not None:
            raise self.error


def test_shutdown_retries_once_past_the_closed_wakeup_pipe():
    pool = _RacingPool(OSError("handle is closed"))
    executors.shut_down(pool)
    assert pool.calls == 2  # the second call sees the pipe closed and joins the manager thread


def test_other_shutdown_errors_are_not_hidden():
    pool = _RacingPool(OSError("disk on fire"))
    with pytest.raises(OSError, match="disk on fire"):
        executors.shut_down(pool)
    assert pool.calls == 1


def test_a_clean_shutdown_is_called_once():
    pool = _RacingPool(None)
    executors.shut_down(pool)
    assert pool.calls == 1
