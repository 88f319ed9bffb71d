"""The job-execution function every worker runs, with scripted stand-ins for the solver.

The stand-ins replace only the numerical solve; storage, the attempt guard, progress writes and
the outcome mapping are the real code on a real SQLite database.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from typing import Any

import pytest

from app.schemas.result import json_ready
from app.settings import Settings
from app.storage import repository
from app.storage.models import Job
from app.storage.session import Database
from app.submission import resolve_submission
from worker.jobs import execute_job

SCENARIO = "rlv-min-heat-load"


def _submit(database: Database, method: dict[str, Any] | None = None) -> str:
    body = {"scenario": SCENARIO, "method": method or {}}
    submission = resolve_submission(body)
    with database.session() as s:
        new = repository.NewJob(
            owner="default", method=submission.method, problem=submission.document
        )
        return repository.create_job(s, new).id


def _job(database: Database, job_id: str) -> Job:
    with database.session() as s:
        job = repository.get_job(s, job_id)
    assert job is not None
    return job


def _record(k: int) -> dict[str, Any]:
    return {"iteration": k, "cost": 10.0 / k, "max_state_change": 1.0 / k, "conic_status": "ok"}


def scripted(
    iterations: int,
    status: str = "succeeded",
    failure: dict[str, str] | None = None,
    between: Callable[[int], None] | None = None,
) -> Callable[..., dict[str, Any]]:
    """A solve that emits ``iterations`` records, honoring ``should_stop`` like the real one."""

    def solve(
        problem: Any, *, on_iteration: Any, should_stop: Any, on_phase: Any = None
    ) -> dict[str, Any]:
        history: list[dict[str, Any]] = []
        for k in range(1, iterations + 1):
            if should_stop():
                return {
                    "status": "cancelled",
                    "failure": {"code": "cancelled", "message": f"before iteration {k}"},
                    "history": history,
                    "timing": {"wall_s": 0.01, "conic_solve_s": 0.0, "iterations": k - 1},
                }
            history.append(_record(k))
            on_iteration(_record(k))
            if between is not None:
                between(k)
        return {
            "status": status,
            "failure": failure,
            "history": history,
            "timing": {"wall_s": 0.25, "conic_solve_s": 0.1, "iterations": iterations},
            "trajectory": {"time_s": [0.0, 1.0]},
            "objective": 1.5,
        }

    return solve


def test_success_stores_result_history_and_progress(settings: Settings, database: Database) -> None:
    job_id = _submit(database)
    notices: list[tuple[str, str]] = []
    status = execute_job(
        job_id,
        settings=settings,
        solve=scripted(3),
        notify=lambda j, kind: notices.append((j, kind)),
    )
    assert status == "succeeded"
    job = _job(database, job_id)
    assert (job.status, job.attempts, job.error_code) == ("succeeded", 1, None)
    assert job.result is not None
    assert job.result["objective"] == 1.5
    assert [r["iteration"] for r in job.history] == [1, 2, 3]
    assert job.progress is not None
    assert job.progress["iteration"] == 3
    assert job.solve_s == 0.25
    assert notices == [(job_id, "iteration")] * 3 + [(job_id, "end")]


def test_progress_is_visible_while_running(settings: Settings, database: Database) -> None:
    job_id = _submit(database)
    seen: list[tuple[str, int, int | None]] = []

    def look(k: int) -> None:
        job = _job(database, job_id)
        seen.append((job.status, len(job.history), (job.progress or {}).get("iteration")))

    execute_job(job_id, settings=settings, solve=scripted(2, between=look))
    assert seen == [("running", 1, 1), ("running", 2, 2)]


def test_solver_failure_keeps_reason_and_history(settings: Settings, database: Database) -> None:
    job_id = _submit(database)
    failure = {"code": "max_iterations", "message": "not converged in 2 iterations"}
    assert execute_job(job_id, settings=settings, solve=scripted(2, "failed", failure)) == "failed"
    job = _job(database, job_id)
    assert (job.error_code, job.error_message) == (failure["code"], failure["message"])
    assert len(job.history) == 2
    assert job.result is not None


def test_exception_in_the_solver_fails_the_job_with_the_history_so_far(
    settings: Settings, database: Database, caplog: pytest.LogCaptureFixture
) -> None:
    def boom(k: int) -> None:
        if k == 2:
            raise RuntimeError("singular matrix at /srv/secret/path")

    job_id = _submit(database)
    with caplog.at_level("ERROR", logger="worker.jobs"):
        assert execute_job(job_id, settings=settings, solve=scripted(5, between=boom)) == "failed"
    job = _job(database, job_id)
    assert job.error_code == "internal_error"
    message = job.error_message or ""
    assert "singular matrix" not in message and "RuntimeError" not in message  # no internals
    error_id = message.split("error id ")[1].split(";")[0]
    logged = [r for r in caplog.records if error_id in r.getMessage()]
    assert logged and "singular matrix" in str(logged[0].exc_info[1])  # the log has them
    assert len(job.history) == 2
    assert job.result is None


class FakeSoftLimitError(Exception):
    """Stands in for Celery's SoftTimeLimitExceeded (raised into the running solve)."""


def test_soft_time_limit_ends_timed_out_keeping_history(
    settings: Settings, database: Database
) -> None:
    def expire(k: int) -> None:
        if k == 3:
            raise FakeSoftLimitError

    job_id = _submit(database)
    status = execute_job(
        job_id,
        settings=settings,
        solve=scripted(10, between=expire),
        timeout_exceptions=(FakeSoftLimitError,),
    )
    assert status == "timed_out"
    job = _job(database, job_id)
    assert (job.status, job.error_code) == ("timed_out", "time_limit")
    assert len(job.history) == 3


def test_own_deadline_ends_timed_out(settings: Settings, database: Database) -> None:
    job_id = _submit(database, {"time_limit_s": 0.05})
    status = execute_job(
        job_id, settings=settings, solve=scripted(50, between=lambda k: time.sleep(0.02))
    )
    assert status == "timed_out"
    job = _job(database, job_id)
    assert job.error_code == "time_limit"
    assert job.result is not None
    assert job.result["status"] == "timed_out"
    assert 1 <= len(job.history) < 50


def test_cancel_while_running_stops_at_the_next_iteration(
    settings: Settings, database: Database
) -> None:
    job_id = _submit(database)

    def cancel_after_two(k: int) -> None:
        if k == 2:
            with database.session() as s:
                repository.request_cancel(s, job_id, "default")

    status = execute_job(job_id, settings=settings, solve=scripted(10, between=cancel_after_two))
    assert status == "cancelled"
    job = _job(database, job_id)
    assert (job.status, job.error_code, len(job.history)) == ("cancelled", "cancelled", 2)


def test_deliveries_of_finished_or_unknown_jobs_do_nothing(
    settings: Settings, database: Database
) -> None:
    job_id = _submit(database)
    execute_job(job_id, settings=settings, solve=scripted(1))
    before = _job(database, job_id)
    assert execute_job(job_id, settings=settings, solve=scripted(4)) == "finished"
    after = _job(database, job_id)
    assert (after.attempts, after.history, after.updated_at) == (
        before.attempts,
        before.history,
        before.updated_at,
    )
    assert execute_job("no-such-job", settings=settings, solve=scripted(1)) == "missing"


def test_a_job_whose_workers_keep_dying_ends_worker_lost(
    settings: Settings, database: Database
) -> None:
    job_id = _submit(database)
    for _ in range(settings.max_attempts):  # each delivery claims, then its process "dies"
        with database.session() as s:  # lease 0 s: the dead worker's lease has lapsed at once
            claim = repository.claim_attempt(s, job_id, settings.max_attempts, lease_s=0.0)
            assert claim.attempt > 0
    assert execute_job(job_id, settings=settings, solve=scripted(1)) == "exhausted"
    job = _job(database, job_id)
    assert (job.status, job.error_code) == ("failed", "worker_lost")


def test_json_ready_replaces_non_finite_numbers() -> None:
    value = {"a": [1.0, math.nan, math.inf], "b": (1, "x"), "c": None}
    assert json_ready(value) == {"a": [1.0, None, None], "b": [1, "x"], "c": None}


def test_the_history_is_stored_once_and_the_result_served_with_it(
    settings: Settings, database: Database
) -> None:
    job_id = _submit(database)
    assert execute_job(job_id, settings=settings, solve=scripted(3)) == "succeeded"
    job = _job(database, job_id)
    assert job.result is not None and job.result["history"] == []
    with database.session() as s:
        text = repository.get_result_text(s, job_id, "default")
    assert text is not None and text.result_json is not None
    assert json.loads(text.result_json)["history"] == [_record(k) for k in (1, 2, 3)]
