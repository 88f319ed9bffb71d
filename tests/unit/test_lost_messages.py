"""The sweeper's lost-message check: a sent queued job that no queue message carries is sent
again only when found so at two checks ``confirm_s`` apart, still queued and not sent again
meanwhile. On a migrated SQLite file with a dispatcher that reports which jobs it carries."""

from __future__ import annotations

from collections.abc import Collection

from app.lost_messages import LostMessages, confirm_interval_s
from app.storage import repository
from app.storage.repository import NewJob
from app.storage.session import Database
from tests.unit.test_service_api import RecordingDispatcher


class Queue(RecordingDispatcher):
    """A dispatcher whose queue carries the jobs in ``carrying``."""

    def __init__(self) -> None:
        super().__init__()
        self.carrying: set[str] | None = set()
        self.asked = 0

    def carried(self, job_ids: Collection[str]) -> set[str] | None:
        self.asked += 1
        return None if self.carrying is None else set(job_ids) & self.carrying


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _sent(database: Database) -> str:
    with database.session() as s:
        job_id = repository.create_job(s, NewJob(owner="o", method="energy-scp", problem={})).id
        repository.mark_dispatched(s, job_id)
    return job_id


def _due(database: Database, job_id: str) -> bool:
    with database.reader() as s:
        job = repository.get_job(s, job_id)
    assert job is not None
    return job.dispatch_due_at is not None


def test_a_job_without_a_message_at_two_checks_apart_is_made_due(database: Database) -> None:
    carried, lost = _sent(database), _sent(database)
    queue, clock = Queue(), Clock()
    queue.carrying = {carried}
    watch = LostMessages(confirm_s=3.0, clock=clock)
    assert watch.check(database, queue) == []  # first seen without a message
    clock.now += 1.0
    assert watch.check(database, queue) == []  # not yet asked again: half the interval
    clock.now += 1.0
    assert watch.check(database, queue) == []  # 2 s apart: not enough
    clock.now += 1.5
    assert watch.check(database, queue) == [lost]
    assert _due(database, lost) and not _due(database, carried)
    assert queue.asked == 3


def test_a_message_seen_again_or_a_new_send_starts_over(database: Database) -> None:
    job_id = _sent(database)
    queue, clock = Queue(), Clock()
    watch = LostMessages(confirm_s=1.0, clock=clock)
    watch.check(database, queue)  # missing
    clock.now += 1.0
    queue.carrying = {job_id}  # it was in flight: found at the second check
    assert watch.check(database, queue) == []
    queue.carrying = set()
    clock.now += 1.0
    assert watch.check(database, queue) == []  # missing once more: a new first sighting
    with database.session() as s:  # sent again meanwhile: another mark
        repository.mark_dispatched(s, job_id)
    clock.now += 1.0
    assert watch.check(database, queue) == []
    clock.now += 1.0
    assert watch.check(database, queue) == [job_id]


def test_nothing_is_concluded_when_the_queue_cannot_tell(database: Database) -> None:
    job_id = _sent(database)
    queue, clock = Queue(), Clock()
    queue.carrying = None
    watch = LostMessages(confirm_s=1.0, clock=clock)
    for _ in range(4):
        assert watch.check(database, queue) == []
        clock.now += 1.0
    assert not _due(database, job_id)


def test_a_job_claimed_meanwhile_is_not_sent_again(database: Database) -> None:
    job_id = _sent(database)
    queue, clock = Queue(), Clock()
    watch = LostMessages(confirm_s=1.0, clock=clock)
    watch.check(database, queue)
    with database.session() as s:
        repository.claim_attempt(s, job_id, 3)
    clock.now += 2.0
    assert watch.check(database, queue) == []
    assert confirm_interval_s(30.0) == 10.0 and confirm_interval_s(2.0) == 1.0
