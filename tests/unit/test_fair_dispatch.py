"""The fair-share rank of a job: how many of its own client's active jobs are ahead of it."""

from __future__ import annotations

from collections.abc import Callable

from app import jobs_service
from app.dispatch.fair import LEVELS, fair_priority
from app.settings import Settings
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


class _Recorder:
    """A dispatcher that records the priorities it is given (nothing runs)."""

    kind = "local"

    def __init__(self) -> None:
        self.priorities: list[int] = []

    def submit(self, job_id: str, limits: object, priority: int = 0) -> None:
        self.priorities.append(priority)


def test_a_submission_is_sent_with_its_fair_rank_and_its_outbox_closed_later(
    database: Database, settings: Settings
) -> None:
    """The rank counted under the client's submission lock is the one dispatch_rank gives,
    without its own transaction; the outbox entry is closed by the deferred task."""
    recorder = _Recorder()
    deferred: list[Callable[[], None]] = []
    body = {"scenario": "rlv-min-heat-load"}
    ids = []
    for owner in ("a", "a", "a", "b"):
        view, _ = jobs_service.submit_job(
            database=database,
            dispatcher=recorder,  # type: ignore[arg-type]
            settings=settings,
            owner=owner,
            body=body,
            idempotency_key=None,
            defer=deferred.append,
        )
        ids.append(view.id)
    assert recorder.priorities == [0, 1, 2, 0]
    assert recorder.priorities == [fair_priority(database, j) for j in ids]
    with database.reader() as s:
        due = [repository.get_job(s, j, None).dispatch_due_at for j in ids]
    assert all(d is not None for d in due)  # sent, not yet recorded as sent
    for task in deferred:
        task()
    with database.reader() as s:
        assert all(repository.get_job(s, j, None).dispatch_due_at is None for j in ids)
