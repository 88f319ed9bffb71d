"""The fair-share rank of a job: how many of its own client's active jobs are ahead of it."""

from __future__ import annotations

from app.dispatch.fair import LEVELS, fair_priority
from app.storage import repository
from app.storage.models import JobStatus
from app.storage.repository import NewJob
from app.storage.session import Database


def _new(db: Database, owner: str) -> str:
    with db.session() as s:
        return repository.create_job(s, NewJob(owner=owner, method="energy-scp", problem={})).id


def test_each_client_ranks_its_own_active_jobs_from_zero(database: Database) -> None:
    a = [_new(database, "a") for _ in range(3)]
    b = _new(database, "b")
    assert [fair_priority(database, j) for j in (*a, b)] == [0, 1, 2, 0]
    with database.session() as s:  # a's first ends: the others move up
        repository.transition(s, a[0], to=JobStatus.SUCCEEDED.value, allowed_from=["queued"])
    assert [fair_priority(database, j) for j in a[1:]] == [0, 1]


def test_a_long_backlog_shares_the_last_level(database: Database) -> None:
    jobs = [_new(database, "a") for _ in range(LEVELS + 3)]
    assert [fair_priority(database, j) for j in jobs] == [*range(LEVELS), *[LEVELS - 1] * 3]
    assert fair_priority(database, "no-such-job") == 0
