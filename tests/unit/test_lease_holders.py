"""Who may take a running job: only a process known to be gone loses it, and an accepted cancel
always wins over a finishing attempt.

Runs on a migrated SQLite file with the real job runner (the numerical solve replaced by a
scripted one where the race is about storage); the lease holder of a claim is the claiming
process, and a dead holder is a real process of this host that has exited.
"""

from __future__ import annotations

import subprocess
import sys
from datetime import timedelta

import pytest
from sqlalchemy import update

from app.dispatch.local import holder_is_gone
from app.settings import Settings
from app.storage import repository
from app.storage.models import Job, process_identity, utcnow
from app.storage.repository import ClaimState, NewJob
from app.storage.session import Database
from app.submission import resolve_submission
from app.sweeper import sweep_once
from tests.unit.test_service_api import RecordingDispatcher
from worker.jobs import execute_job


def _new(db: Database) -> str:
    submission = resolve_submission({"scenario": "rlv-min-heat-load"})
    new = NewJob(owner="o", method=submission.method, problem=submission.document)
    with db.session() as s:
        return repository.create_job(s, new).id


def _claim(db: Database, job_id: str, lease_s: float = 3600.0) -> int:
    with db.session() as s:
        claim = repository.claim_attempt(s, job_id, 3, lease_s)
    assert claim.state is ClaimState.CLAIMED
    return claim.attempt


def _job(db: Database, job_id: str) -> Job:
    with db.reader() as s:
        job = repository.get_job(s, job_id)
    assert job is not None
    return job


def _set_holder(db: Database, job_id: str, holder: str) -> None:
    with db.session() as s:
        s.execute(update(Job).where(Job.id == job_id).values(lease_holder=holder))


@pytest.fixture(scope="module")
def dead_pid() -> int:
    """The pid of a process of this host that has exited."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_a_claim_records_the_claiming_process_as_holder(database: Database) -> None:
    job_id = _new(database)
    _claim(database, job_id)
    assert _job(database, job_id).lease_holder == process_identity()


def test_only_a_process_of_this_host_that_has_exited_is_gone(dead_pid: int) -> None:
    assert holder_is_gone(process_identity(dead_pid))
    assert not holder_is_gone(process_identity())  # this process
    assert not holder_is_gone(f"another-host/{dead_pid}")  # cannot be checked: presumed alive
    assert not holder_is_gone("garbage")


def test_start_up_recovery_takes_only_jobs_whose_process_is_gone(
    database: Database, dead_pid: int
) -> None:
    live, dead, elsewhere = _new(database), _new(database), _new(database)
    for job_id in (live, dead, elsewhere):
        _claim(database, job_id)
    _set_holder(database, dead, process_identity(dead_pid))
    _set_holder(database, elsewhere, f"another-host/{dead_pid}")
    with database.session() as s:
        assert repository.release_dead_holders(s, holder_is_gone) == [dead]
    statuses = [_job(database, j).status for j in (live, dead, elsewhere)]
    assert statuses == ["running", "queued", "running"]
    assert _claim(database, dead) == 2  # the attempt count still applies


def test_shutdown_makes_the_lease_lapse_for_the_next_sweeper(
    database: Database, dead_pid: int, settings: Settings
) -> None:
    live, dead = _new(database), _new(database)
    _claim(database, live)
    _claim(database, dead)
    _set_holder(database, dead, process_identity(dead_pid))
    with database.session() as s:
        assert repository.release_dead_holders(s, holder_is_gone, requeue=False) == [dead]
    assert _job(database, dead).status == "running"
    dispatcher = RecordingDispatcher()
    report = sweep_once(database, dispatcher, settings, now=utcnow() + timedelta(seconds=0.1))
    assert report.requeued == [dead]
    assert [job for job, _ in dispatcher.submitted] == [dead]
    assert _job(database, live).status == "running"


def test_a_cancel_accepted_before_the_outcome_is_stored_ends_the_job_cancelled(
    database: Database, settings: Settings
) -> None:
    """The race of a DELETE answered 202 while the solve finishes: the job must not end
    ``succeeded``."""
    job_id = _new(database)

    def solve(problem: object, **callbacks: object) -> dict[str, object]:
        with database.session() as s:  # the client's DELETE lands after the last stop check
            cancelled = repository.request_cancel(s, job_id, "o")
        assert cancelled is not None and cancelled.status == "running"
        return {"status": "succeeded", "history": [{"iteration": 1}], "timing": {"wall_s": 0.1}}

    assert execute_job(job_id, settings=settings, solve=solve) == "cancelled"
    job = _job(database, job_id)
    assert (job.status, job.error_code) == ("cancelled", "cancelled")
    assert job.result is not None and job.result["status"] == "cancelled"
    assert "after the solve had ended succeeded" in (job.error_message or "")
    assert job.history == [{"iteration": 1}]


def test_a_finished_job_refuses_a_later_cancel(database: Database, settings: Settings) -> None:
    job_id = _new(database)

    def solve(problem: object, **callbacks: object) -> dict[str, object]:
        return {"status": "succeeded", "history": [], "timing": {"wall_s": 0.1}}

    execute_job(job_id, settings=settings, solve=solve)
    with database.session() as s:
        job = repository.request_cancel(s, job_id, "o")
    assert job is not None and job.status == "succeeded"


def test_a_queued_job_held_by_a_gone_or_silent_server_is_released_and_sent_again(
    database: Database, dead_pid: int, settings: Settings
) -> None:
    """A queued job handed to a server's pool is held by that server; the sweeper of any
    server frees it once that server's process is gone or its hold lapsed, never while the
    hold is renewed."""
    live, gone, silent, elsewhere = (_new(database) for _ in range(4))
    with database.session() as s:
        assert repository.hold_queued(s, live, process_identity(), 60.0)
        assert repository.hold_queued(s, gone, process_identity(dead_pid), 60.0)
        assert repository.hold_queued(s, silent, "another-host/1", 0.5)
        assert repository.hold_queued(s, elsewhere, "another-host/2", 60.0)
        for job_id in (live, gone, silent, elsewhere):
            repository.mark_dispatched(s, job_id)
    dispatcher = RecordingDispatcher()
    report = sweep_once(database, dispatcher, settings, now=utcnow() + timedelta(seconds=1))
    assert sorted(report.taken_over) == sorted([gone, silent])
    assert sorted(j for j, _ in dispatcher.submitted) == sorted([gone, silent])
    assert [_job(database, j).lease_holder for j in (live, elsewhere)] == [
        process_identity(),
        "another-host/2",
    ]
    with database.session() as s:  # a renewed hold keeps its job past its first expiry
        assert repository.renew_holds(s, "another-host/2", 3600.0) == 1
    later = utcnow() + timedelta(seconds=120)
    assert sweep_once(database, dispatcher, settings, now=later).taken_over == [live]
    assert _job(database, elsewhere).lease_holder == "another-host/2"


def test_a_starting_pool_takes_only_the_queued_jobs_no_live_server_holds(
    database: Database, dead_pid: int
) -> None:
    free, mine, gone, lapsed, held = (_new(database) for _ in range(5))
    with database.session() as s:
        repository.hold_queued(s, mine, "me/1", 60.0)
        repository.hold_queued(s, gone, process_identity(dead_pid), 60.0)
        repository.hold_queued(s, lapsed, "another-host/1", -1.0)
        repository.hold_queued(s, held, "another-host/2", 60.0)
        taken = repository.take_queued(s, "me/1", 30.0, holder_is_gone)
    assert taken == [free, mine, gone, lapsed]
    assert {_job(database, j).lease_holder for j in taken} == {"me/1"}
    assert _job(database, held).lease_holder == "another-host/2"
    assert all(_job(database, j).dispatch_due_at is None for j in taken)
