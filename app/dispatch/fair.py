"""Fair shares between clients: a job's dispatch priority is its rank among its client's jobs.

A job is sent with the priority of how many of its client's jobs, queued or running, are ahead
of it (0 for a client's first, up to :data:`LEVELS` − 1). Workers take the lowest level first
(the broker's priority lists, or the embedded pool's heap) and, within a level, the oldest: a
client with one job waits for at most one of another client's jobs per free worker, however
many that client has queued. Beyond the last level a client's backlog is first come, first
served.
"""

from __future__ import annotations

from app.storage import repository
from app.storage.session import Database
from worker.celery_app import PRIORITY_LEVELS as LEVELS


def priority_of_rank(rank: int) -> int:
    """The dispatch priority of a job with ``rank`` of its client's jobs ahead of it."""
    return min(rank, LEVELS - 1)


def fair_priority(database: Database, job_id: str) -> int:
    """The dispatch priority of ``job_id``: its client's jobs ahead of it, at most LEVELS − 1."""
    with database.reader() as session:
        rank = repository.dispatch_rank(session, job_id)
    return priority_of_rank(rank)
