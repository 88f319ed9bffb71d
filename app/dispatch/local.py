"""Embedded dispatch: run jobs in a pool of local processes, through the same ``execute_job``.

Used when no broker is configured. The request returns at once; a spawned process does the
CPU-bound solve. Jobs left queued or running by a previous server process are re-dispatched at
start-up (the attempt counter still applies), and a pool broken by a dying child is rebuilt.
"""

from __future__ import annotations

import functools
import logging
import multiprocessing
import signal
import threading
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

from app.settings import Settings
from app.storage import repository
from app.storage.session import get_database
from worker.limits import TimeLimits

log = logging.getLogger(__name__)


def _init_child() -> None:
    # Ctrl+C goes to the whole process group; the server decides when children stop.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s [%(name)s] %(message)s")


def _run_job(job_id: str, settings: Settings) -> str:
    from worker.jobs import execute_job

    return execute_job(job_id, settings=settings)


def _warm_up() -> None:
    import worker.jobs

    try:
        import worker.solver.api  # noqa: F401
        from worker.solver.dynamics_compiled import warm_up

        warm_up()  # compiled kernels: built (first run on a machine) or loaded before any job
    except Exception:  # the first real job reports any import problem
        log.debug("solver import failed during warm-up", exc_info=True)


class LocalDispatcher:
    """A process pool of ``settings.local_workers`` processes running ``execute_job``."""

    kind = "local"

    def __init__(self, settings: Settings) -> None:
        self._settings = settings
        self.on_done: Callable[[str], None] | None = None
        """Called with the job id when a job's process returns (from a pool thread)."""
        self._lock = threading.Lock()
        self._executor: ProcessPoolExecutor | None = None
        self._pending: dict[str, Future[str]] = {}
        self._closed = False

    def _new_executor(self) -> ProcessPoolExecutor:
        executor = ProcessPoolExecutor(
            max_workers=self._settings.local_workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_init_child,
        )
        for _ in range(self._settings.local_workers):
            executor.submit(_warm_up)
        return executor

    def start(self) -> None:
        """Start the pool and re-dispatch jobs a previous server process left unfinished."""
        with self._lock:
            self._executor = self._new_executor()
        self.resubmit_unfinished()

    def resubmit_unfinished(self) -> None:
        """Hand every stored queued or running job to the pool again.

        Called at start-up and after the pool broke, when no process of this pool runs any job:
        running jobs are orphans, so they are put back to ``queued`` at once instead of waiting
        for their lease to lapse.
        """
        database = get_database(self._settings.effective_database_url)
        with database.session() as session:
            released = repository.release_running(session)
            job_ids = repository.active_job_ids(session)
        if released:
            log.info("%d interrupted job(s) put back in the queue", released)
        for job_id in job_ids:
            log.info("re-dispatching unfinished job %s", job_id)
            self.submit(job_id, TimeLimits(0, 0, 0))

    def submit(self, job_id: str, limits: TimeLimits) -> None:
        """Queue the job in the pool (limits are applied inside ``execute_job``)."""
        with self._lock:
            if self._executor is None or self._closed:
                raise RuntimeError("the local job pool is not running")
            future = self._executor.submit(_run_job, job_id, self._settings)
            self._pending[job_id] = future
        future.add_done_callback(functools.partial(self._done, job_id))

    def _done(self, job_id: str, future: Future[str]) -> None:
        with self._lock:
            if self._pending.get(job_id) is future:
                del self._pending[job_id]
        if future.cancelled():
            return
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

    def ping(self) -> str | None:
        """``None`` while the pool accepts work."""
        with self._lock:
            if self._executor is None or self._closed:
                return "local job pool not running"
            if getattr(self._executor, "_broken", False):
                return "local job pool broken (restarting)"
        return None

    def queue_depth(self) -> int | None:
        """Jobs handed to the pool that have not started yet."""
        with self._lock:
            return sum(1 for f in self._pending.values() if not f.running() and not f.done())

    def shutdown(self) -> None:
        """Stop the pool without waiting; unfinished jobs resume at the next start."""
        with self._lock:
            self._closed = True
            executor, self._executor = self._executor, None
        if executor is None:
            return
        processes = list((getattr(executor, "_processes", None) or {}).values())
        executor.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            if process.is_alive():
                process.terminate()
