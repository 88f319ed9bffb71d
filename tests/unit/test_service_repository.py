"""Job storage: forward-only status changes, the attempt guard, cancellation, idempotency keys.

Runs on a migrated SQLite file here; ``tests/integration`` runs the same tests on PostgreSQL.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from alembic import command
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from sqlalchemy.exc import IntegrityError

from app.storage import repository
from app.storage.migrate import alembic_config, upgrade_database
from app.storage.models import Base, JobStatus
from app.storage.repository import ClaimState, NewJob
from app.storage.session import Database, create_db_engine

PROBLEM = {"method": {"name": "energy-scp", "time_limit_s": 10}}


@pytest.fixture
def database(tmp_path: Path) -> Iterator[Database]:
    engine = create_db_engine(f"sqlite:///{tmp_path / 'jobs.sqlite3'}")
    upgrade_database(engine)
    yield Database.for_engine(engine)
    engine.dispose()


def _new(db: Database, owner: str = "alice", key: str | None = None) -> str:
    with db.session() as s:
        return repository.create_job(
            s, NewJob(owner=owner, method="energy-scp", problem=PROBLEM, idempotency_key=key)
        ).id


def _status(db: Database, job_id: str) -> str:
    with db.session() as s:
        job = repository.get_job(s, job_id)
        assert job is not None
        return job.status


def test_migrations_match_the_models(database: Database) -> None:
    with database.engine.connect() as connection:
        diff = compare_metadata(MigrationContext.configure(connection), Base.metadata)
    assert diff == []


def test_create_and_owner_scoping(database: Database) -> None:
    job_id = _new(database)
    with database.session() as s:
        job = repository.get_job(s, job_id, "alice")
        assert job is not None
        assert (job.status, job.attempts, job.history) == ("queued", 0, [])
        assert job.created_at.tzinfo is not None
        assert repository.get_job(s, job_id, "mallory") is None


def test_attempts_are_counted_and_exhausted_jobs_fail_as_worker_lost(database: Database) -> None:
    job_id = _new(database)
    for expected in (1, 2, 3):
        with database.session() as s:  # lease 0 s: each worker is gone before the next delivery
            claim = repository.claim_attempt(s, job_id, max_attempts=3, lease_s=0.0)
        assert claim == repository.Claim(ClaimState.CLAIMED, expected)
        assert _status(database, job_id) == "running"
    with database.session() as s:
        claim = repository.claim_attempt(s, job_id, max_attempts=3)
    assert claim.state is ClaimState.EXHAUSTED
    with database.session() as s:
        job = repository.get_job(s, job_id)
        assert job is not None
        assert (job.status, job.error_code, job.attempts) == ("failed", "worker_lost", 3)
        assert job.finished_at is not None


def test_duplicate_delivery_of_a_finished_job_changes_nothing(database: Database) -> None:
    job_id = _new(database)
    with database.session() as s:
        attempt = repository.claim_attempt(s, job_id, 3).attempt
        assert repository.transition(
            s,
            job_id,
            to="succeeded",
            allowed_from=["running"],
            attempt=attempt,
            values={"result": {"status": "succeeded"}, "history": [{"iteration": 1}]},
        )
    with database.session() as s:
        assert repository.claim_attempt(s, job_id, 3).state is ClaimState.FINISHED
        assert not repository.transition(s, job_id, to="running", allowed_from=["queued"])
        assert not repository.transition(s, job_id, to="failed", allowed_from=["running"])
        assert not repository.record_iteration(s, job_id, attempt, [], {"iteration": 9})
    with database.session() as s:
        job = repository.get_job(s, job_id)
        assert job is not None
        assert (job.status, job.attempts, job.result) == ("succeeded", 1, {"status": "succeeded"})
        assert job.history == [{"iteration": 1}]


def test_a_stale_attempt_cannot_write(database: Database) -> None:
    job_id = _new(database)
    with database.session() as s:
        first = repository.claim_attempt(s, job_id, 3, lease_s=0.0).attempt  # its worker dies
    with database.session() as s:
        second = repository.claim_attempt(s, job_id, 3).attempt  # redelivered elsewhere
    with database.session() as s:
        assert not repository.record_iteration(s, job_id, first, [{"iteration": 1}], {})
        assert repository.should_stop(s, job_id, first)
        assert not repository.should_stop(s, job_id, second)
        assert repository.record_iteration(s, job_id, second, [{"iteration": 1}], {"iteration": 1})
        assert not repository.transition(
            s, job_id, to="succeeded", allowed_from=["running"], attempt=first
        )
        assert repository.transition(
            s, job_id, to="succeeded", allowed_from=["running"], attempt=second
        )


def test_only_one_concurrent_finisher_wins(database: Database) -> None:
    job_id = _new(database)
    with database.session() as s:
        attempt = repository.claim_attempt(s, job_id, 3).attempt
    wins: list[str] = []
    barrier = threading.Barrier(4)

    def finish(status: str) -> None:
        barrier.wait()
        with database.session() as s:
            if repository.transition(
                s, job_id, to=status, allowed_from=["running"], attempt=attempt
            ):
                wins.append(status)

    threads = [
        threading.Thread(target=finish, args=(s,))
        for s in ("succeeded", "failed", "timed_out", "cancelled")
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(wins) == 1
    assert _status(database, job_id) == wins[0]


def test_cancel_queued_running_and_finished(database: Database) -> None:
    queued, running, done = _new(database), _new(database), _new(database)
    with database.session() as s:
        attempt = repository.claim_attempt(s, running, 3).attempt
        repository.claim_attempt(s, done, 3)
        repository.transition(s, done, to="succeeded", allowed_from=["running"])
    with database.session() as s:
        job = repository.request_cancel(s, queued, "alice")
        assert job is not None
        assert (job.status, job.cancel_requested) == ("cancelled", True)
        job = repository.request_cancel(s, running, "alice")
        assert job is not None
        assert (job.status, job.cancel_requested) == ("running", True)
        assert repository.should_stop(s, running, attempt)
        job = repository.request_cancel(s, done, "alice")
        assert job is not None
        assert job.status == "succeeded"
        assert repository.request_cancel(s, queued, "mallory") is None
        # a cancelled queued job is never started by a late delivery
        assert repository.claim_attempt(s, queued, 3).state is ClaimState.FINISHED


def test_redelivery_of_a_cancel_requested_running_job_ends_it(database: Database) -> None:
    job_id = _new(database)
    with database.session() as s:
        repository.claim_attempt(s, job_id, 3, lease_s=0.0)
        repository.request_cancel(s, job_id, "alice")
    with database.session() as s:  # the worker died before it saw the flag
        assert repository.claim_attempt(s, job_id, 3).state is ClaimState.CANCELLED
    assert _status(database, job_id) == "cancelled"


def test_idempotency_keys_are_unique_per_owner(database: Database) -> None:
    _new(database, "alice", "k1")
    _new(database, "bob", "k1")
    _new(database, "alice", None)
    _new(database, "alice", None)
    with pytest.raises(IntegrityError):
        _new(database, "alice", "k1")
    with database.session() as s:
        job = repository.find_by_idempotency_key(s, "alice", "k1")
        assert job is not None
        assert job.owner == "alice"


def test_listing_filters_and_pages(database: Database) -> None:
    ids = [_new(database) for _ in range(5)]
    _new(database, owner="bob")
    with database.session() as s:
        repository.transition(s, ids[0], to="cancelled", allowed_from=["queued"])
    with database.session() as s:
        page, total = repository.list_jobs(s, "alice", limit=2, offset=0)
        assert total == 5
        assert len(page) == 2
        rest, _ = repository.list_jobs(s, "alice", limit=10, offset=2)
        assert len({j.id for j in page} | {j.id for j in rest}) == 5
        cancelled, total = repository.list_jobs(s, "alice", ["cancelled"])
        assert (total, [j.id for j in cancelled]) == (1, [ids[0]])
        assert repository.active_job_ids(s)[:4] == ids[1:]  # oldest first


def test_counts_and_solve_time_histogram(database: Database) -> None:
    times = [0.05, 0.3, 2.0]
    for solve_s in times:
        job_id = _new(database)
        with database.session() as s:
            repository.transition(
                s, job_id, to="succeeded", allowed_from=["queued"], values={"solve_s": solve_s}
            )
    _new(database)
    with database.session() as s:
        counts = repository.count_by_status(s)
        histogram = repository.solve_time_histogram(s, [0.1, 1.0, 10.0])
    assert counts["succeeded"] == 3
    assert counts["queued"] == 1
    assert set(counts) == {status.value for status in JobStatus}
    assert histogram.cumulative == (1, 2, 3)
    assert histogram.count == 3
    # sums of three short binary fractions: exact to rounding, so 1e-12 is ample
    assert histogram.total == pytest.approx(sum(times), abs=1e-12)


def _stored_history(db: Database, job_id: str) -> list[dict[str, Any]]:
    with db.session() as s:
        job = repository.get_job(s, job_id)
        assert job is not None
        return list(job.history)


def test_history_is_appended_per_iteration_and_stored_once(database: Database) -> None:
    job_id = _new(database)
    records = [{"iteration": k, "cost": 1.0 / k, "extra": {"x": [0.1, 1e-300]}} for k in (1, 2, 3)]
    with database.session() as s:
        attempt = repository.claim_attempt(s, job_id, 3).attempt
    for k in range(1, 4):
        with database.session() as s:
            assert repository.record_iteration(s, job_id, attempt, records[:k], {"iteration": k})
        assert _stored_history(database, job_id) == records[:k]
    with database.session() as s:  # a write committed though its caller saw an error: sent again
        assert repository.record_iteration(s, job_id, attempt, records, {"iteration": 3})
        assert repository.complete_history(s, job_id, attempt, records, ["running"])
    assert _stored_history(database, job_id) == records
    result = {"status": "succeeded", "history": records, "timing": {"wall_s": 1.0}}
    with database.session() as s:
        stored = repository.result_for_storage(result)
        assert repository.transition(
            s,
            job_id,
            to="succeeded",
            allowed_from=["running"],
            attempt=attempt,
            values={"result": stored},
        )
        job = repository.get_job(s, job_id)
        assert job is not None and job.result is not None
        assert job.result["history"] == []  # kept once, in the job's history
        text = repository.get_result_text(s, job_id, "alice")
    assert text is not None and text.result_json is not None
    assert json.loads(text.result_json) == result


def test_lost_iteration_writes_are_completed_when_the_outcome_is_stored(
    database: Database,
) -> None:
    job_id = _new(database)
    records = [{"iteration": k} for k in range(1, 6)]
    with database.session() as s:
        attempt = repository.claim_attempt(s, job_id, 3).attempt
        assert repository.record_iteration(s, job_id, attempt, records[:1], {})
        # iterations 2 and 3 were lost (the database was away); 4 carries them along
        assert repository.record_iteration(s, job_id, attempt, records[:4], {})
        assert repository.complete_history(s, job_id, attempt, records, ["running", "queued"])
    assert _stored_history(database, job_id) == records


def test_a_retried_attempt_keeps_its_history_apart(database: Database) -> None:
    job_id = _new(database)
    with database.session() as s:
        first = repository.claim_attempt(s, job_id, 3, lease_s=0.0).attempt
        assert repository.record_iteration(s, job_id, first, [{"iteration": 1, "a": 1}], {}, 0.0)
    with database.session() as s:
        second = repository.claim_attempt(s, job_id, 3).attempt
    assert _stored_history(database, job_id) == []
    with database.session() as s:  # the first attempt's worker comes back: fenced off
        late = [{"iteration": 1, "a": 1}, {"iteration": 2, "a": 1}]
        assert not repository.record_iteration(s, job_id, first, late, {})
        assert not repository.complete_history(s, job_id, first, late, ["running", "queued"])
        assert repository.record_iteration(s, job_id, second, [{"iteration": 1, "a": 2}], {})
    assert _stored_history(database, job_id) == [{"iteration": 1, "a": 2}]


def test_a_result_without_history_is_served_as_stored(database: Database) -> None:
    job_id = _new(database)
    result = {"status": "failed", "failure": {"code": "unsupported_by_method", "message": "x"}}
    with database.session() as s:
        assert repository.result_for_storage(result) is result
        repository.transition(
            s, job_id, to="failed", allowed_from=["queued"], values={"result": result}
        )
        text = repository.get_result_text(s, job_id, "alice")
    assert text is not None and text.result_json is not None
    assert json.loads(text.result_json) == result


def test_migration_0005_moves_the_history_out_of_stored_results(database: Database) -> None:
    job_id = _new(database)
    history = [{"iteration": 1, "cost": 2.5}, {"iteration": 2, "cost": 1.25}]
    config = alembic_config()
    with database.engine.begin() as connection:
        config.attributes["connection"] = connection
        command.downgrade(config, "0004")
    with database.session() as s:
        repository.transition(
            s,
            job_id,
            to="succeeded",
            allowed_from=["queued"],
            values={"result": {"status": "succeeded", "history": history}, "history": history},
        )
    upgrade_database(database.engine)
    with database.session() as s:
        job = repository.get_job(s, job_id)
        assert job is not None and job.result is not None
        assert (job.result["history"], job.history) == ([], history)
        text = repository.get_result_text(s, job_id, "alice")
    assert text is not None and text.result_json is not None
    assert json.loads(text.result_json)["history"] == history


def test_an_outcome_is_stored_in_one_statement_only_when_the_history_length_is_known(
    database: Database,
) -> None:
    job_id = _new(database)
    records = [{"iteration": k} for k in range(1, 4)]
    with database.autocommit() as s:
        attempt = repository.claim_attempt(s, job_id, 3).attempt
        # the attempt knows 0 records are stored, but one is: a write it saw fail went through
        assert repository.record_iteration(s, job_id, attempt, records[:1], {}, stored=None)
        assert repository.record_iteration(s, job_id, attempt, records[:2], {}, stored=1)
        assert repository.record_iteration(s, job_id, attempt, records[:2], {}, stored=0)
    assert _stored_history(database, job_id) == records[:2]  # never appended twice
    outcome = {"to": "failed", "allowed_from": ["running"], "values": {"error_code": "x"}}
    with database.autocommit() as s:
        assert not repository.store_outcome(
            s,
            job_id,
            attempt=attempt,
            history=records,
            stored=1,
            unless_cancel_requested=True,
            **outcome,  # type: ignore[arg-type]
        )
        assert repository.store_outcome(
            s,
            job_id,
            attempt=attempt,
            history=records,
            stored=2,
            unless_cancel_requested=True,
            **outcome,  # type: ignore[arg-type]
        )
        job = repository.get_job(s, job_id)
    assert job is not None and (job.status, job.error_code) == ("failed", "x")
    assert _stored_history(database, job_id) == records


def test_a_result_is_served_with_its_history_as_the_same_json_values(database: Database) -> None:
    job_id = _new(database)
    history = [{"iteration": 1, "cost": 1e-300, "note": "Δv ≈ 0"}]
    result = {"status": "failed", "history": history, "x": [1.5, 2.5e-7, None, "é"]}
    with database.session() as s:
        attempt = repository.claim_attempt(s, job_id, 3).attempt
        assert repository.record_iteration(s, job_id, attempt, history, {})
        stored = repository.result_for_storage(result)
        assert repository.transition(
            s, job_id, to="failed", allowed_from=["running"], values={"result": stored}
        )
        text = repository.get_result_text(s, job_id, "alice")
    assert text is not None and text.result_json is not None
    assert json.loads(text.result_json) == result
