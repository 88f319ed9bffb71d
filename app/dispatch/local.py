"""Embedded dispatch: run jobs in a pool of local processes, through the same ``execute_job``.

Used when no broker is configured. The request returns at once; a spawned process does the
CPU-bound solve. The pool loads the solver (compiling its kernels on the first start after an
install; its processes tell it which) before it reports ready. At start-up, jobs whose process
is known to be gone (a process of this host that no longer exists held their lease) go back to
the queue, and queued jobs are dispatched; a job another live server or worker runs is never
taken: if that process dies, its lease lapses and the sweeper re-queues it. A pool broken by a
dying child is rebuilt the same way.

A queued job handed to this pool is *held* by this server (``lease_holder`` is the server's
``host/pid``, ``lease_expires_at`` a hold renewed every third of ``TRAJOPT_LEASE_S``): another
server on the same database leaves it alone while the hold is renewed, and takes it over (its
sweeper makes it due, its relay sends it to its own pool) once this server's process is gone or
its hold lapsed, as it does with a running job whose lease lapsed.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import gc
import heapq
import itertools
import logging
import multiprocessing
import os
import signal
import socket
import threading
import time
from collections.abc import Callable, Collection
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

from app.dispatch.fair import fair_priority
from app.failure_log import FailureLog
from app.settings import Settings
from app.storage import repository
from app.storage.models import process_identity, utcnow
from app.storage.session import get_database
from worker.limits import TimeLimits
from worker.solver import FIRST_COMPILE

log = logging.getLogger(__name__)

PARENT_WATCH_INTERVAL_S = 1.0
"""How often a pool process checks that the server that started it is still alive."""
STOP_JOIN_TIMEOUT_S = 10.0
"""How long shutdown waits for each killed pool process to be reaped."""
UNKNOWN, LOADING, COMPILING = 0, 1, 2
"""What the pool's processes do before they take jobs (the shared ``kernels`` flag): not known
yet, loading the solver's kernels from numba's cache, or compiling them (first after an
install)."""
WARMING_UP = {
    UNKNOWN: "starting: loading the solver",
    LOADING: "starting: loading the solver's kernels from numba's cache",
    COMPILING: (
        f"starting: compiling the solver's kernels (once after an install, {FIRST_COMPILE})"
    ),
}
"""The readiness check's answer while the pool warms up, by the ``kernels`` flag."""
WAIT_PHASE = {UNKNOWN: "loading", LOADING: "loading", COMPILING: "compiling"}
"""The progress phase of a job queued while the pool warms up, by the ``kernels`` flag."""
_kernels_flag: ctypes.c_int | None = None
"""In a pool process: the pool's shared ``kernels`` flag (set by :func:`_init_child`): shared
memory without a lock (no semaphore to release at shutdown); the processes all find the same
cache, and a process that compiles ends the warm-up before another could report loading."""


def holder_is_gone(holder: str) -> bool:
    """Whether the process named by a lease holder ``host/pid`` is known to no longer exist:
    only a process of this host can be checked; any other is presumed alive."""
    host, _, pid_text = holder.rpartition("/")
    if host != socket.gethostname() or not pid_text.isdigit():
        return False
    try:
        os.kill(int(pid_text), 0)
    except ProcessLookupError:
        return True
    except PermissionError:  # exists, owned by someone else
        return False
    return False


def _watch_parent(parent_pid: int) -> None:
    while True:
        time.sleep(PARENT_WATCH_INTERVAL_S)
        if os.getppid() != parent_pid:  # the server died (kill -9): do not run on as an orphan
            os._exit(1)


def _init_child(parent_pid: int, kernels: ctypes.c_int | None = None) -> None:
    global _kernels_flag
    _kernels_flag = kernels
    # Ctrl+C, or a SIGTERM sent to the whole process group (a service manager stopping the
    # server), reaches these processes too; the server decides when they stop (it kills them
    # in its shutdown, and they exit by themselves if it dies).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s [%(name)s] %(message)s")
    threading.Thread(
        target=_watch_parent, args=(parent_pid,), name="trajopt-parent-watch", daemon=True
    ).start()


def _run_job(job_id: str, settings: Settings) -> str:
    from worker.jobs import execute_job

    return execute_job(job_id, settings=settings)


def _warm_up() -> float:
    """Import the solver and load (or, first after an install, compile) its kernels; seconds."""
    start = time.perf_counter()
    import worker.jobs
    import worker.solver.api  # noqa: F401
    from worker.solver.warmup import kernels_cached, warm_up

    if _kernels_flag is not None:
        state = LOADING if kernels_cached() else COMPILING
        _kernels_flag.value = max(_kernels_flag.value, state)
    warm_up()
    return time.perf_counter() - start


class LocalDispatcher:
    """A process pool of ``settings.local_workers`` processes running ``execute_job``."""

    kind = "local"

    def __init__(self, settings: Settings) -> None:
        self._settings = settings
        self.holder = process_identity()
        """``host/pid`` of this server: the holder of the queued jobs its pool holds."""
        self._stop_holding = threading.Event()
        self._holds = threading.Thread(
            target=self._renew_holds, name="trajopt-pool-holds", daemon=True
        )
        self.on_done: Callable[[str], None] | None = None
        """Called with the job id when a job's process returns (from a pool thread)."""
        self._lock = threading.Lock()
        self._executor: ProcessPoolExecutor | None = None
        self._pending: dict[str, Future[str]] = {}
        self._waiting: list[tuple[int, int, str]] = []
        """Jobs not yet handed to the pool: a heap of (priority, arrival, job id)."""
        self._arrivals = itertools.count()
        self._warming: list[Future[float]] = []
        self._kernels: ctypes.c_int | None = None
        self._closed = False

    def _new_executor(self) -> ProcessPoolExecutor:
        context = multiprocessing.get_context("spawn")
        self._kernels = context.RawValue(ctypes.c_int, UNKNOWN)
        executor = ProcessPoolExecutor(
            max_workers=self._settings.local_workers,
            mp_context=context,
            initializer=_init_child,
            initargs=(os.getpid(), self._kernels),
        )
        started = time.perf_counter()
        self._warming = [executor.submit(_warm_up) for _ in range(self._settings.local_workers)]
        self._warming[0].add_done_callback(functools.partial(self._warmed, started))
        return executor

    def _warmed(self, started: float, future: Future[float]) -> None:
        if future.cancelled():
            return
        error = future.exception()
        if error is not None and self._closed:  # a shutdown (Ctrl+C) while the pool was loading
            log.info("the job pool stopped before the solver was loaded")
            return
        if error is not None:
            log.error("the solver could not be loaded in the job pool", exc_info=error)
            return
        log.info("solver loaded in the job pool in %.1f s", time.perf_counter() - started)

    def start(self) -> None:
        """Start the pool and dispatch the stored jobs that wait for a process."""
        with self._lock:
            self._executor = self._new_executor()
        self._holds.start()
        self.resubmit_unfinished()

    def resubmit_unfinished(self) -> None:
        """Re-queue the running jobs whose process is gone, then take every queued job no live
        server's pool holds (unheld, held here, or held by a server gone or silent) into this
        pool.

        A job queued here and also in another server's pool (a hold taken over from a server
        that was only slow) runs once: the first delivery claims it and the other finds it
        busy or finished.
        """
        database = get_database(self._settings.effective_database_url)
        with database.session() as session:
            released = repository.release_dead_holders(session, holder_is_gone)
            job_ids = repository.take_queued(
                session, self.holder, self._settings.lease_s, holder_is_gone
            )
        if released:
            log.info("%d interrupted job(s) put back in the queue", len(released))
        with self._lock:
            waiting = {entry[2] for entry in self._waiting}
        for job_id in job_ids:
            if job_id in waiting:
                continue
            log.info("dispatching unfinished job %s", job_id)
            self._enqueue(job_id, fair_priority(database, job_id))

    def submit(self, job_id: str, limits: TimeLimits, priority: int = 0) -> None:
        """Hold the job for this server's pool and queue it (limits are applied inside
        ``execute_job``): it goes to the pool when a process is free, lowest ``priority``
        first, then oldest. While the pool still loads the solver, the queued job's progress
        says so (phase ``compiling`` when it compiles the kernels, else ``loading``)."""
        with self._lock:
            if self._executor is None or self._closed:
                raise RuntimeError("the local job pool is not running")
            warming = not any(f.done() for f in self._warming)
        database = get_database(self._settings.effective_database_url)
        with database.session() as session:
            repository.hold_queued(
                session,
                job_id,
                self.holder,
                self._settings.lease_s,
                {"phase": WAIT_PHASE[self._kernel_state()]} if warming else None,
            )
        self._enqueue(job_id, priority)

    def _enqueue(self, job_id: str, priority: int) -> None:
        """Put the job in the waiting heap and feed the pool."""
        with self._lock:
            if self._executor is None or self._closed:
                raise RuntimeError("the local job pool is not running")
            heapq.heappush(self._waiting, (priority, next(self._arrivals), job_id))
        self._feed()

    def _kernel_state(self) -> int:
        """What the pool's processes do before they take jobs (UNKNOWN, LOADING, COMPILING)."""
        flag = self._kernels
        return int(flag.value) if flag is not None else UNKNOWN

    def _renew_holds(self) -> None:
        """Renew the holds of the queued jobs this pool holds, every third of the lease."""
        interval = self._settings.lease_s / 3.0
        database = get_database(self._settings.effective_database_url)
        failures = FailureLog(log, "local pool")
        while not self._stop_holding.wait(interval):
            try:
                with database.autocommit() as session:  # one UPDATE
                    repository.renew_holds(session, self.holder, self._settings.lease_s)
            except Exception as exc:  # retried at the next tick
                failures.failed(exc, "renew the holds of its queued jobs", "retrying")
                continue
            failures.succeeded("holds renewed again")

    def _feed(self) -> None:
        """Hand waiting jobs to the pool while it has a free process."""
        while True:
            with self._lock:
                if self._executor is None or self._closed or not self._waiting:
                    return
                if len(self._pending) >= self._settings.local_workers:
                    return
                entry = heapq.heappop(self._waiting)
                job_id = entry[2]
                try:
                    future = self._executor.submit(_run_job, job_id, self._settings)
                except BrokenProcessPool:  # being rebuilt: it re-dispatches every queued job
                    heapq.heappush(self._waiting, entry)
                    return
                self._pending[job_id] = future
            future.add_done_callback(functools.partial(self._done, job_id))

    def _done(self, job_id: str, future: Future[str]) -> None:
        with self._lock:
            if self._pending.get(job_id) is future:
                del self._pending[job_id]
        if future.cancelled():
            return
        self._feed()
        if self.on_done is not None:
            self.on_done(job_id)
        exc = future.exception()
        if isinstance(exc, BrokenProcessPool):
            threading.Thread(target=self._rebuild, name="trajopt-pool-rebuild", daemon=True).start()
        elif exc is not None:
            log.error("job %s: worker process raised", job_id, exc_info=exc)

    def _rebuild(self) -> None:
        with self._lock:
            if self._closed or self._executor is None:
                return
            broken = self._executor
            if not getattr(broken, "_broken", False):
                return
            log.warning("a job process died; restarting the local pool")
            self._executor = self._new_executor()
        broken.shutdown(wait=False, cancel_futures=True)
        self.resubmit_unfinished()

    def carried(self, job_ids: Collection[str]) -> set[str] | None:
        """Not known here: the jobs this pool holds are marked held in the database."""
        return None

    def ping(self) -> str | None:
        """``None`` while the pool accepts work and has the solver loaded."""
        with self._lock:
            if self._executor is None or self._closed:
                return "local job pool not running"
            if getattr(self._executor, "_broken", False):
                return "local job pool broken (restarting)"
            if not any(f.done() for f in self._warming):
                return WARMING_UP[self._kernel_state()]
        return None

    def queue_depth(self) -> int | None:
        """Jobs waiting for a process of the pool."""
        with self._lock:
            handed = sum(1 for f in self._pending.values() if not f.running() and not f.done())
            return len(self._waiting) + handed

    def shutdown(self) -> None:
        """Stop the pool's processes, then make the leases of the jobs they ran lapse at once:
        another server on the same database re-queues them at its next sweep, this one at its
        next start (their attempt count still applies)."""
        with self._lock:
            self._closed = True
            executor, self._executor = self._executor, None
        if executor is None:
            return
        self._stop_holding.set()
        if self._holds.is_alive():
            self._holds.join(timeout=STOP_JOIN_TIMEOUT_S)
        processes = list((getattr(executor, "_processes", None) or {}).values())
        for process in processes:  # an interrupted solve keeps nothing worth a graceful stop
            if process.is_alive():
                process.kill()
        for process in processes:
            process.join(STOP_JOIN_TIMEOUT_S)
        # the executor's own thread and queues end once its processes are gone; collecting
        # them now releases their semaphores before the interpreter exits (no leak warning)
        with contextlib.suppress(Exception):
            executor.shutdown(wait=True, cancel_futures=True)
        self._warming = []
        del executor, processes
        gc.collect()
        try:
            database = get_database(self._settings.effective_database_url)
            with database.session() as session:
                released = repository.release_dead_holders(session, holder_is_gone, requeue=False)
                handed_back = repository.release_holds(
                    session, utcnow(), lambda holder: holder == self.holder, lapsed=False
                )
        except Exception:  # their leases and holds lapse by themselves
            log.warning("could not release the interrupted jobs", exc_info=True)
            return
        if released:
            log.info("%d interrupted job(s) released for the next sweep or start", len(released))
        if handed_back:
            log.info("%d queued job(s) handed back for another server or the next start",
                     len(handed_back))  # fmt: skip
