"""The dispatcher interface the API uses to hand a stored job to a worker."""

from __future__ import annotations

from collections.abc import Collection
from typing import Protocol

from worker.limits import TimeLimits


class Dispatcher(Protocol):
    """Sends job ids to workers; the job itself is read from the database by the worker."""

    kind: str
    """``"celery"`` or ``"local"``, shown by ``/readyz``."""

    def start(self) -> None:
        """Prepare connections or processes (called once at application start-up)."""

    def submit(self, job_id: str, limits: TimeLimits, priority: int = 0) -> None:
        """Queue ``job_id`` at ``priority`` (0 first, see ``app.dispatch.fair``); raises when the
        job could not be handed over."""

    def carried(self, job_ids: Collection[str]) -> set[str] | None:
        """Which of ``job_ids`` a message of the queue still carries to a worker (waiting, or
        delivered to a live worker that has not yet acknowledged it); ``None`` when the queue
        cannot tell (the local pool: its queued jobs are held in the database instead)."""

    def ping(self) -> str | None:
        """``None`` if the queue is reachable, else a short reason."""

    def queue_depth(self) -> int | None:
        """Jobs waiting for a worker, if known."""

    def shutdown(self) -> None:
        """Release connections or processes (called once at application shutdown)."""
