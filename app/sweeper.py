"""The lease sweeper: finds running jobs whose worker stopped renewing its lease and acts.

A lapsed lease means the worker is gone (killed, out of memory, hard time limit, lost machine).
The job is re-queued while it has attempts left, ends ``timed_out`` (history kept) when its own
time limit has passed, and ``failed``/``worker_lost`` after the attempt cap. Queued jobs left
untouched for long are sent again (their message may have died with a broker). Every change is
a conditional update, so several API processes can sweep the same database.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime

from app.dispatch import Dispatcher
from app.settings import Settings
from app.storage import repository
from app.storage.models import JobStatus, utcnow
from app.storage.session import Database
from worker.limits import TimeLimits, job_time_limits

log = logging.getLogger(__name__)

EndNotice = Callable[[str], None]


@dataclass
class SweepReport:
    """What one sweep did, by job id."""

    requeued: list[str] = field(default_factory=list)
    timed_out: list[str] = field(default_factory=list)
    worker_lost: list[str] = field(default_factory=list)
    cancelled: list[str] = field(default_factory=list)
    resent: list[str] = field(default_factory=list)


def _elapsed(started_at: datetime | None, now: datetime) -> float:
    return (now - started_at).total_seconds() if started_at is not None else 0.0


def sweep_once(
    database: Database,
    dispatcher: Dispatcher,
    settings: Settings,
    now: datetime | None = None,
    on_end: EndNotice | None = None,
    unsent: set[str] | None = None,
) -> SweepReport:
    """Handle every lapsed running job and re-send stale queued ones; returns what changed.

    ``unsent`` holds ids whose re-send failed (broker down); they are tried again first.
    """
    now = now or utcnow()
    report = SweepReport()
    unsent = unsent if unsent is not None else set()
    for job_id in sorted(unsent):
        with database.reader() as session:
            row = repository.get_job(session, job_id)
        if row is None or row.status != JobStatus.QUEUED.value:
            unsent.discard(job_id)
        elif _send(dispatcher, job_id, job_time_limits(row.problem, settings)):
            unsent.discard(job_id)
            report.resent.append(job_id)
    with database.reader() as session:
        lapsed = repository.lapsed_running_jobs(session, now)
    for job in lapsed:
        limits = job_time_limits(job.problem, settings)
        elapsed = _elapsed(job.started_at, now)
        with database.session() as session:
            if job.cancel_requested:
                done = repository.finish_lapsed(
                    session, job.id, job.attempts, now, JobStatus.CANCELLED.value,
                    "cancelled", "cancelled on request; its worker stopped before finishing",
                )  # fmt: skip
                bucket = report.cancelled
            elif elapsed >= limits.solve_s:
                done = repository.finish_lapsed(
                    session, job.id, job.attempts, now, JobStatus.TIMED_OUT.value, "time_limit",
                    f"the worker stopped answering after the job's time limit of "
                    f"{limits.solve_s:g} s (hard time limit); history kept",
                )  # fmt: skip
                bucket = report.timed_out
            elif job.attempts >= settings.max_attempts:
                done = repository.finish_lapsed(
                    session, job.id, job.attempts, now, JobStatus.FAILED.value, "worker_lost",
                    f"the job was started {job.attempts} times and its worker was lost each "
                    "time; giving up",
                )  # fmt: skip
                bucket = report.worker_lost
            else:
                done = repository.requeue_lapsed(session, job.id, job.attempts, now)
                bucket = report.requeued
        if not done:
            continue  # it moved meanwhile (renewed, finished, or another sweeper acted)
        bucket.append(job.id)
        if bucket is report.requeued:
            log.warning("job %s: worker lost during attempt %d; re-queued", job.id, job.attempts)
            if not _send(dispatcher, job.id, limits):
                unsent.add(job.id)
        else:
            log.warning("job %s: worker lost during attempt %d; ended", job.id, job.attempts)
            if on_end is not None:
                on_end(job.id)
    if settings.requeue_queued_after_s > 0:
        with database.session() as session:
            stale = repository.claim_stale_queued(session, now, settings.requeue_queued_after_s)
        for job_id in stale:
            with database.reader() as session:
                row = repository.get_job(session, job_id)
            if row is not None:
                log.warning("job %s: still queued; sending it again", job_id)
                if _send(dispatcher, job_id, job_time_limits(row.problem, settings)):
                    report.resent.append(job_id)
                else:
                    unsent.add(job_id)
    return report


def _send(dispatcher: Dispatcher, job_id: str, limits: TimeLimits) -> bool:
    try:
        dispatcher.submit(job_id, limits)
    except Exception as exc:  # stays queued; the next sweep tries again
        log.warning("job %s: could not be sent now: %s: %s", job_id, type(exc).__name__, exc)
        return False
    return True


class Sweeper:
    """Runs :func:`sweep_once` every ``settings.sweep_interval_s`` in a daemon thread."""

    def __init__(
        self,
        database: Database,
        dispatcher: Dispatcher,
        settings: Settings,
        on_end: EndNotice | None = None,
    ) -> None:
        self._args = (database, dispatcher, settings)
        self._on_end = on_end
        self._interval = settings.sweep_interval_s
        self._unsent: set[str] = set()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="trajopt-sweeper", daemon=True)

    def start(self) -> None:
        """Start sweeping in the background."""
        self._thread.start()

    def stop(self) -> None:
        """Stop after the current sweep."""
        self._stop.set()
        self._thread.join(timeout=10.0)

    def _run(self) -> None:
        while not self._stop.wait(self._interval):
            try:
                sweep_once(*self._args, on_end=self._on_end, unsent=self._unsent)
            except Exception:  # the database may be briefly away; try again next time
                log.warning("lease sweep failed", exc_info=True)
