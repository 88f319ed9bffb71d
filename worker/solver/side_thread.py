"""One helper thread per process, for solver work that can overlap the main thread's.

The compiled kernels (``models.bank_state_sweeps``) release the GIL, so a kernel submitted here
runs on a second core while the main thread goes on (the time-domain SCP integrates the
curvature of the interval maps beside the maps themselves). The thread is created on first use
and again after a fork (a Celery prefork child does not inherit its parent's threads); with a
single CPU available ``available()`` is False and callers run the work in line.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import ParamSpec, TypeVar

P = ParamSpec("P")
T = TypeVar("T")

_lock = threading.Lock()
_executor: tuple[int, ThreadPoolExecutor] | None = None


def available() -> bool:
    """Whether this process may use more than one CPU (a helper thread then pays off)."""
    try:
        return len(os.sched_getaffinity(0)) > 1
    except AttributeError:  # platforms without CPU affinity
        return (os.cpu_count() or 1) > 1


def submit(fn: Callable[P, T], *args: P.args, **kwargs: P.kwargs) -> Future[T]:
    """Run ``fn(*args, **kwargs)`` on this process's helper thread; its future."""
    global _executor
    with _lock:
        if _executor is None or _executor[0] != os.getpid():
            pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="solver-side")
            _executor = (os.getpid(), pool)
        return _executor[1].submit(fn, *args, **kwargs)


def completed(value: T) -> Future[T]:
    """A future that already holds ``value``: work done in line, behind the same interface."""
    future: Future[T] = Future()
    future.set_result(value)
    return future
