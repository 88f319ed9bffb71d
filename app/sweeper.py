"""The sweeper and the dispatch relay: what keeps every accepted job moving.

The relay sends every queued job that is due (the jobs table is a transactional outbox: a job is
stored due, the submitting request sends it and marks it sent; if that request's process dies or
the broker refuses, the relay of any API process sends it within seconds). The sweeper finds
running jobs whose worker stopped renewing its lease: a lapsed lease means the worker is gone
(killed, out of memory, hard time limit, lost machine). The job is re-queued while it has
attempts left, ends ``timed_out`` (history kept) when the attempt had run for its whole time
limit, and ``failed``/``worker_lost`` after the attempt cap. Queued jobs left untouched for long
are made due again (their message may have died with a broker). A sent queued job that no
queue message carries any more (its worker died while taking it) is sent again within about a
lease (:mod:`app.lost_messages`), and so is a queued job held by the local pool of a server that
is gone (its process no longer exists, or it stopped renewing its hold). After the database was
unreachable, leases and holds get one lease period of grace: workers could not renew them
either. Every change is a conditional update, so several API processes can sweep the same
database. Failures are logged once per streak, then at growing intervals (:mod:`app.failure_log`).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime

from app.dispatch import Dispatcher
from app.dispatch.fair import fair_priority
from app.dispatch.local import holder_is_gone
from app.failure_log import FailureLog
from app.lost_messages import LostMessages, confirm_interval_s
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
    lost_messages: list[str] = field(default_factory=list)
    taken_over: list[str] = field(default_factory=list)


def sweep_once(
    database: Database,
    dispatcher: Dispatcher,
    settings: Settings,
    now: datetime | None = None,
    on_end: EndNotice | None = None,
    lapse_checks: bool = True,
    lost: LostMessages | None = None,
    send_failures: FailureLog | None = None,
) -> SweepReport:
    """Handle every lapsed running job and lapsed pool hold (unless ``lapse_checks`` is off:
    the grace after a database outage), take over the queued jobs of a server that is gone,
    make stale queued jobs due, and those ``lost`` finds without a message, then relay every
    due job; returns what changed."""
    now = now or utcnow()
    report = SweepReport()
    if lapse_checks:
        _handle_lapsed(database, settings, now, on_end, report)
    with database.session() as session:
        report.taken_over.extend(
            repository.release_holds(session, now, holder_is_gone, lapsed=lapse_checks)
        )
    for job_id in report.taken_over:
        log.warning("job %s: the server whose pool held it is gone; taking it over", job_id)
    if settings.requeue_queued_after_s > 0:
        with database.session() as session:
            stale = repository.claim_stale_queued(session, now, settings.requeue_queued_after_s)
        for job_id in stale:
            log.warning("job %s: still queued; sending it again", job_id)
    if lost is not None:
        report.lost_messages.extend(lost.check(database, dispatcher))
    report.resent.extend(relay_once(database, dispatcher, settings, now, send_failures))
    return report


def _handle_lapsed(
    database: Database,
    settings: Settings,
    now: datetime,
    on_end: EndNotice | None,
    report: SweepReport,
) -> None:
    with database.reader() as session:
        lapsed = repository.lapsed_running_jobs(session, now)
    for job in lapsed:
        limits = job_time_limits(job.problem, settings)
        ran = job.running_s(settings.lease_s)
        with database.session() as session:
            if job.cancel_requested:
                done = repository.finish_lapsed(
                    session, job.id, job.attempts, now, JobStatus.CANCELLED.value,
                    "cancelled", "cancelled on request; its worker stopped before finishing",
                )  # fmt: skip
                bucket = report.cancelled
            elif ran >= limits.solve_s:
                done = repository.finish_lapsed(
                    session, job.id, job.attempts, now, JobStatus.TIMED_OUT.value, "time_limit",
                    f"the worker stopped answering after running {ran:.0f} s, past the job's "
                    f"time limit of {limits.solve_s:g} s (hard time limit); history kept",
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
            log.warning(
                "job %s: worker lost during attempt %d after %.0f s; re-queued",
                job.id,
                job.attempts,
                ran,
            )
        else:
            log.warning("job %s: worker lost during attempt %d; ended", job.id, job.attempts)
            if on_end is not None:
                on_end(job.id)


def relay_once(
    database: Database,
    dispatcher: Dispatcher,
    settings: Settings,
    now: datetime | None = None,
    failures: FailureLog | None = None,
) -> list[str]:
    """Send every queued job that is due (never sent, re-queued, or its sender gone); returns
    the ids sent. A job whose send fails stays due and is tried again at the next relay (the
    failures logged through ``failures`` when given: once, then at growing intervals)."""
    now = now or utcnow()
    with database.session() as session:
        due = repository.claim_due_dispatches(session, now)
    sent = []
    for job_id in due:
        with database.reader() as session:
            row = repository.get_job(session, job_id)
        if row is None or row.status != JobStatus.QUEUED.value:
            continue
        limits = job_time_limits(row.problem, settings)
        if not _send(dispatcher, job_id, limits, fair_priority(database, job_id), failures):
            continue
        with database.session() as session:
            repository.mark_dispatched(session, job_id, now)
        sent.append(job_id)
    if sent:
        log.info("relay sent %d queued job(s)", len(sent))
    return sent


def _send(
    dispatcher: Dispatcher,
    job_id: str,
    limits: TimeLimits,
    priority: int,
    failures: FailureLog | None,
) -> bool:
    try:
        dispatcher.submit(job_id, limits, priority)
    except Exception as exc:  # stays queued; the next sweep tries again
        if failures is not None:
            failures.failed(exc, f"send job {job_id}", "it stays due; the relay tries again")
        else:
            log.warning("job %s: could not be sent now: %s: %s", job_id, type(exc).__name__, exc)
        return False
    if failures is not None:
        failures.succeeded("queued jobs are sent again")
    return True


class Sweeper:
    """Runs :func:`relay_once` every ``settings.relay_interval_s`` and :func:`sweep_once` every
    ``settings.sweep_interval_s`` in a daemon thread."""

    def __init__(
        self,
        database: Database,
        dispatcher: Dispatcher,
        settings: Settings,
        on_end: EndNotice | None = None,
    ) -> None:
        self._args = (database, dispatcher, settings)
        self._on_end = on_end
        self._settings = settings
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="trajopt-sweeper", daemon=True)
        self._failures = FailureLog(log, "sweeper")
        self._send_failures = FailureLog(log, "relay")
        self._lost = LostMessages(confirm_interval_s(settings.lease_s))
        self._grace_until = 0.0

    def start(self) -> None:
        """Start sweeping in the background."""
        self._thread.start()

    def stop(self) -> None:
        """Stop after the current sweep."""
        self._stop.set()
        self._thread.join(timeout=10.0)

    def _run(self) -> None:
        settings = self._settings
        tick = min(settings.relay_interval_s, settings.sweep_interval_s)
        next_sweep = 0.0
        while not self._stop.wait(tick):
            now = time.monotonic()
            try:
                if now >= next_sweep:
                    next_sweep = now + settings.sweep_interval_s
                    sweep_once(
                        *self._args,
                        on_end=self._on_end,
                        lapse_checks=now >= self._grace_until,
                        lost=self._lost,
                        send_failures=self._send_failures,
                    )
                else:
                    relay_once(*self._args, failures=self._send_failures)
            except Exception as exc:  # the database may be briefly away; try again next time
                self._failures.failed(exc, "sweep", f"retrying every {tick:g} s")
                continue
            if self._failures.failures:  # back: workers renew their leases now, give them time
                self._grace_until = time.monotonic() + settings.lease_s
                self._failures.succeeded(
                    f"database reachable again; leases get {settings.lease_s:.0f} s of grace"
                )
