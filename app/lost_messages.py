"""Queued jobs whose queue message is lost: sent, still queued, and carried by no message.

A Celery worker takes a message from Redis in two steps: it pops it from the queue's list, then
records it as delivered (kombu's ``unacked`` hash). A worker killed between the two takes the
message with it, and one killed after recording it but before claiming the job leaves it in the
hash, where only the visibility timeout (an hour) would bring it back. Either way the job stays
``queued``, marked sent, and nothing will run it.

The sweeper asks the queue which of the sent queued jobs a message still carries
(:meth:`app.dispatch.Dispatcher.carried`). A job found without one at two checks at least
``confirm_s`` apart, still queued and not sent again meanwhile (the same send mark), is made due
again by a conditional update, and the relay sends it. A message on its way from the list to the
hash is so for microseconds, and a worker about to claim a job holds its message in the hash, so
neither is taken for lost twice in a row. A needless resend is harmless anyway: a duplicate
delivery finds the job running or finished and does nothing.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from datetime import datetime

from app.dispatch import Dispatcher
from app.storage import repository
from app.storage.models import utcnow
from app.storage.session import Database

log = logging.getLogger(__name__)


def confirm_interval_s(lease_s: float) -> float:
    """How far apart the two checks that find a message lost must be: a third of the lease
    (at least a second), so a lost message is resent within about a lease."""
    return max(1.0, lease_s / 3.0)


class LostMessages:
    """The sent queued jobs found without a message at the last check, and since when."""

    def __init__(self, confirm_s: float, clock: Callable[[], float] = time.monotonic) -> None:
        self._confirm_s = confirm_s
        self._clock = clock
        self._missing: dict[str, tuple[datetime, float]] = {}
        """job id -> (its send mark, when it was first found without a message)."""
        self._next_check = 0.0

    def check(self, database: Database, dispatcher: Dispatcher) -> list[str]:
        """Compare the sent queued jobs with the queue's messages (at most every half
        ``confirm_s``) and make due again the jobs found lost twice; returns their ids."""
        now = self._clock()
        if now < self._next_check:
            return []
        self._next_check = now + self._confirm_s / 2.0
        with database.reader() as session:  # before the queue: a job claimed meanwhile is
            sent = repository.sent_queued_jobs(session)  # no longer queued at the resend
        if not sent:
            self._missing.clear()
            return []
        carried = dispatcher.carried([job_id for job_id, _ in sent])
        if carried is None:  # the queue cannot tell now: conclude nothing
            return []
        missing: dict[str, tuple[datetime, float]] = {}
        resent: list[str] = []
        for job_id, mark in sent:
            if job_id in carried:
                continue
            seen = self._missing.get(job_id)
            if seen is None or seen[0] != mark:  # first seen without a message (this send)
                missing[job_id] = (mark, now)
            elif now - seen[1] < self._confirm_s:
                missing[job_id] = seen
            elif self._resend(database, job_id, mark, now - seen[1]):
                resent.append(job_id)
        self._missing = missing
        return resent

    @staticmethod
    def _resend(database: Database, job_id: str, mark: datetime, apart_s: float) -> bool:
        with database.session() as session:
            done = repository.resend_lost(session, job_id, mark, utcnow())
        if done:
            log.warning(
                "job %s: sent, still queued, and no queue message carries it (two checks "
                "%.1f s apart); sending it again",
                job_id,
                apart_s,
            )
        return done
