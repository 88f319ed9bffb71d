"""Leases, the sweeper and key management: lost workers are detected by the service itself.

Runs on a migrated SQLite file with a recording dispatcher; the sweeper is called with an
explicit clock so lapsed leases need no waiting.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path

import pytest
from pydantic import ValidationError
from sqlalchemy import update

from app.cli import main as cli_main
from app.settings import Settings
from app.storage import repository
from app.storage.migrate import upgrade_database
from app.storage.models import Job, utcnow
from app.storage.repository import ClaimState, NewJob
from app.storage.session import Database, create_db_engine
from app.sweeper import sweep_once
from tests.unit.test_service_api import RecordingDispatcher
from worker.heartbeat import Heartbeat
from worker.solver.solve_clock import WALL_FACTOR

PROBLEM = {"method": {"name": "energy-scp", "time_limit_s": 60}}
LEASE_S = 30.0


@pytest.fixture
def database(tmp_path: Path) -> Iterator[Database]:
    engine = create_db_engine(f"sqlite:///{tmp_path / 'jobs.sqlite3'}")
    upgrade_database(engine)
    yield Database.for_engine(engine)
    engine.dispose()


@pytest.fixture
def settings(tmp_path: Path) -> Settings:
    return Settings(data_dir=tmp_path, lease_s=LEASE_S, max_attempts=3)


def _new(db: Database, problem: dict[str, object] | None = None) -> str:
    with db.session() as s:
        new = NewJob(owner="alice", method="energy-scp", problem=problem or PROBLEM)
        return repository.create_job(s, new).id


def _claim(db: Database, job_id: str, lease_s: float = LEASE_S) -> int:
    with db.session() as s:
        claim = repository.claim_attempt(s, job_id, 3, lease_s)
    assert claim.state is ClaimState.CLAIMED
    return claim.attempt


def _job(db: Database, job_id: str) -> repository.Job:
    with db.reader() as s:
        job = repository.get_job(s, job_id)
    assert job is not None
    return job


def test_a_duplicate_delivery_of_a_live_job_does_not_start_it_again(database: Database) -> None:
    job_id = _new(database)
    _claim(database, job_id)
    with database.session() as s:
        assert repository.claim_attempt(s, job_id, 3, LEASE_S).state is ClaimState.BUSY
    assert _job(database, job_id).attempts == 1


def test_sweeper_requeues_a_lapsed_job_and_leaves_live_ones(
    database: Database, settings: Settings
) -> None:
    lapsed, live = _new(database), _new(database)
    _claim(database, lapsed, lease_s=1.0)
    _claim(database, live, lease_s=3600.0)
    with database.session() as s:
        repository.record_iteration(s, lapsed, 1, [{"iteration": 1}], {"iteration": 1}, 1.0)
    dispatcher = RecordingDispatcher()
    later = utcnow() + timedelta(seconds=5)  # past the 1 s lease, inside the 60 s time limit
    report = sweep_once(database, dispatcher, settings, now=later)
    assert report.requeued == [lapsed]
    assert [job_id for job_id, _ in dispatcher.submitted] == [lapsed]
    job = _job(database, lapsed)
    assert (job.status, job.attempts, job.lease_expires_at) == ("queued", 1, None)
    assert _job(database, live).status == "running"
    assert sweep_once(database, dispatcher, settings, now=later).requeued == []  # done once
    assert _claim(database, lapsed) == 2  # the re-sent delivery starts attempt 2
    with database.session() as s:  # the first attempt can no longer write
        assert not repository.record_iteration(s, lapsed, 1, [], {}, LEASE_S)


def test_sweeper_ends_jobs_past_their_time_limit_or_attempts(
    database: Database, settings: Settings
) -> None:
    runaway = _new(database, {"method": {"name": "energy-scp", "time_limit_s": 2}})
    exhausted, cancelled = _new(database), _new(database)
    _claim(database, runaway)
    # it ran 9 s of the 8 s wall-clock limit of its 2 CPU s before its worker was lost
    _started_ago(database, runaway, WALL_FACTOR * 2 + 1.0)
    with database.session() as s:
        history = [{"iteration": 1}, {"iteration": 2}]
        assert repository.record_iteration(s, runaway, 1, history, {"iteration": 2}, LEASE_S)
    for _ in range(3):
        _claim(database, exhausted, lease_s=0.0)
    _claim(database, cancelled, lease_s=1.0)
    with database.session() as s:
        repository.request_cancel(s, cancelled, "alice")
    dispatcher = RecordingDispatcher()
    report = sweep_once(database, dispatcher, settings, now=utcnow() + timedelta(seconds=40))
    assert (report.timed_out, report.worker_lost, report.cancelled) == (
        [runaway],
        [exhausted],
        [cancelled],
    )
    assert dispatcher.submitted == []
    job = _job(database, runaway)
    assert (job.status, job.error_code) == ("timed_out", "time_limit")
    assert [r["iteration"] for r in job.history] == [1, 2]  # the history is kept
    job = _job(database, exhausted)
    assert (job.status, job.error_code, job.attempts) == ("failed", "worker_lost", 3)
    assert _job(database, cancelled).status == "cancelled"


def _started_ago(db: Database, job_id: str, seconds: float) -> None:
    with db.session() as s:
        s.execute(
            update(Job)
            .where(Job.id == job_id)
            .values(started_at=utcnow() - timedelta(seconds=seconds))
        )


def test_a_worker_lost_near_the_end_of_its_budget_is_retried_not_timed_out(
    database: Database, settings: Settings
) -> None:
    """Only the time the attempt ran counts against its limit, not the time it took to notice
    that its worker was gone."""
    job_id = _new(database, {"method": {"name": "energy-scp", "time_limit_s": 2}})
    _claim(database, job_id)
    _started_ago(database, job_id, 1.5)  # 1.5 s of its 2 s, then the worker died
    with database.session() as s:  # its last sign of life, now
        assert repository.renew_lease(s, job_id, 1, LEASE_S)
    dispatcher = RecordingDispatcher()
    later = utcnow() + timedelta(seconds=35)  # noticed long after the 2 s had passed
    report = sweep_once(database, dispatcher, settings, now=later)
    assert (report.requeued, report.timed_out) == ([job_id], [])
    assert [j for j, _ in dispatcher.submitted] == [job_id]


def test_stale_queued_jobs_are_sent_again_once(database: Database, settings: Settings) -> None:
    job_id = _new(database)
    dispatcher = RecordingDispatcher()
    now = utcnow()
    assert sweep_once(database, dispatcher, settings, now=now).resent == []
    later = now + timedelta(seconds=settings.requeue_queued_after_s + 1)
    assert sweep_once(database, dispatcher, settings, now=later).resent == [job_id]
    assert sweep_once(database, dispatcher, settings, now=later).resent == []
    assert [job_id for job_id, _ in dispatcher.submitted] == [job_id]


def test_heartbeat_renews_the_lease_until_the_attempt_is_no_longer_owner(
    database: Database,
) -> None:
    job_id = _new(database)
    attempt = _claim(database, job_id, lease_s=0.3)
    first = _job(database, job_id).lease_expires_at
    beat = Heartbeat(database, job_id, attempt, lease_s=0.3)
    beat.start()
    try:
        time.sleep(0.5)  # several 0.1 s renewal periods
        renewed = _job(database, job_id).lease_expires_at
        assert first is not None and renewed is not None and renewed > first
        with database.session() as s:  # the sweeper re-queued it meanwhile
            assert repository.requeue_lapsed(s, job_id, attempt, utcnow() + timedelta(hours=1))
        deadline = time.monotonic() + 2.0
        while not beat.lost and time.monotonic() < deadline:
            time.sleep(0.05)
        assert beat.lost
    finally:
        beat.stop()


def test_api_keys_mode_refuses_missing_or_default_secrets(tmp_path: Path) -> None:
    for secret in ("", "changeme", "short-but-random-3f9a"):
        with pytest.raises(ValidationError, match="TRAJOPT_API_KEY_SECRET"):
            Settings(data_dir=tmp_path, auth_mode="api-keys", api_key_secret=secret)
    with pytest.raises(ValidationError, match="default password"):
        Settings(
            data_dir=tmp_path,
            auth_mode="api-keys",
            api_key_secret="f" * 64,
            database_url="postgresql://trajopt:postgres@db:5432/trajopt",
        )
    Settings(data_dir=tmp_path, auth_mode="api-keys", api_key_secret="0f" * 32)


def test_keys_command_creates_lists_and_revokes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from app.settings import get_settings

    for name in ("DATABASE_URL", "TRAJOPT_DATABASE_URL", "REDIS_URL", "TRAJOPT_BROKER_URL"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("TRAJOPT_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("TRAJOPT_AUTH_MODE", "api-keys")
    monkeypatch.setenv("TRAJOPT_API_KEY_SECRET", "ab" * 32)
    get_settings.cache_clear()
    try:
        assert cli_main(["keys", "create", "--client", "team-a"]) == 0
        key = capsys.readouterr().out.strip()
        assert key.startswith("tj_") and len(key) >= 40
        assert cli_main(["keys", "list"]) == 0
        listing = capsys.readouterr().out
        assert "team-a" in listing and key not in listing
        key_id = listing.splitlines()[1].split()[0]
        assert cli_main(["keys", "revoke", key_id]) == 0
        assert cli_main(["keys", "revoke", key_id]) == 1  # already revoked
        assert cli_main(["keys", "list", "--client", "team-a"]) == 0
        assert capsys.readouterr().out.splitlines()[-1].split()[-1] != "-"  # revoked time
        monkeypatch.setenv("TRAJOPT_AUTH_MODE", "single-user")
        monkeypatch.setenv("TRAJOPT_API_KEY_SECRET", "changeme")
        get_settings.cache_clear()
        assert cli_main(["keys", "create", "--client", "team-b"]) == 2  # refuses a weak secret
    finally:
        get_settings.cache_clear()


def test_a_requeue_that_cannot_be_sent_is_retried_at_the_next_sweep(
    database: Database, settings: Settings
) -> None:
    from tests.unit.test_security_api import FailingDispatcher

    job_id = _new(database)
    _claim(database, job_id, lease_s=1.0)
    later = utcnow() + timedelta(seconds=5)
    report = sweep_once(database, FailingDispatcher(), settings, now=later)
    assert (report.requeued, report.resent) == ([job_id], [])
    job = _job(database, job_id)
    assert job.status == "queued" and job.dispatch_due_at is not None  # still due
    dispatcher = RecordingDispatcher()  # the broker is back
    retry = later + timedelta(seconds=repository.DISPATCH_CLAIM_S)
    report = sweep_once(database, dispatcher, settings, now=retry)
    assert report.resent == [job_id]
    assert [j for j, _ in dispatcher.submitted] == [job_id]
    assert _job(database, job_id).dispatch_due_at is None
    assert sweep_once(database, dispatcher, settings, now=retry).resent == []
