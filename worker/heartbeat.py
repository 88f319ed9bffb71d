"""The lease heartbeat of a running attempt: a thread that keeps the job's lease fresh.

The lease is also renewed with every stored iteration; the thread covers long iterations and the
final verification. If the process dies (kill -9, hard time limit, lost machine) the renewals
stop, the lease lapses, and the service's sweeper re-queues or ends the job.
"""

from __future__ import annotations

import logging
import threading

from app.failure_log import FailureLog
from app.storage import repository
from app.storage.session import Database

log = logging.getLogger(__name__)


class Heartbeat:
    """Renews ``job_id``'s lease for ``attempt`` every ``lease_s / 3`` seconds until stopped."""

    def __init__(self, database: Database, job_id: str, attempt: int, lease_s: float) -> None:
        self._database = database
        self._job_id = job_id
        self._attempt = attempt
        self._lease_s = lease_s
        self._stop = threading.Event()
        self.lost = False
        """True once a renewal found that the attempt no longer owns the job."""
        self._thread = threading.Thread(
            target=self._run, name=f"trajopt-lease-{job_id[:8]}", daemon=True
        )

    def start(self) -> None:
        """Start renewing in the background."""
        self._thread.start()

    def stop(self, wait: bool = True) -> None:
        """Stop renewing (the attempt is over) and, with ``wait``, wait for the thread (a
        renewal still under way is fenced by the attempt: it cannot touch a finished job)."""
        self._stop.set()
        if wait:
            self.join()

    def join(self) -> None:
        """Wait for the thread to end after :meth:`stop`."""
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)

    def _run(self) -> None:
        interval = self._lease_s / 3.0
        failures = FailureLog(log, f"job {self._job_id}")
        while not self._stop.wait(interval):
            try:
                with self._database.autocommit() as session:  # one fenced UPDATE
                    owned = repository.renew_lease(
                        session, self._job_id, self._attempt, self._lease_s
                    )
            except Exception as exc:  # a missed renewal is retried at the next tick
                failures.failed(exc, "renew its lease", f"retrying every {interval:.1f} s")
                continue
            failures.succeeded("lease renewed again")
            if not owned:
                self.lost = True
                return
