"""No accepted job stranded: an API killed between storing a job and sending it, an API killed
during a burst of submissions, a database outage with running and queued jobs, and a worker lost
near the end of a job's time limit, each on real PostgreSQL, Redis, Celery workers and uvicorn.

The database outage goes through a TCP forwarder the test cuts and restores, so the machine's
shared PostgreSQL server keeps running for other tests.
"""

from __future__ import annotations

import itertools
import os
import signal
import threading
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import make_url

from app.settings import normalize_database_url
from app.storage import repository
from app.storage.session import get_database
from app.submission import resolve_submission
from bench.tcp_proxy import TcpProxy
from tests.integration.conftest import PgSchemas
from tests.integration.harness import (
    SCENARIO,
    TERMINAL,
    ApiServer,
    create_api_key,
    forget_queue,
    long_job,
)
from tests.integration.test_faults import (
    FAULT_SETTINGS,
    SMALL,
    Workers,
    _running_for,
    assert_counts,
    kill_children,
    rows,
    running_with_progress,
    wait_all_terminal,
    wait_for_row,
)

pytestmark = pytest.mark.slow

STRANDED_S = 30.0
"""Acceptance: no accepted job waits longer than this after its API or database is back."""


@pytest.fixture
def proxy() -> Iterator[TcpProxy]:
    forwarder = TcpProxy("127.0.0.1", 5432)
    forwarder.start()
    yield forwarder
    forwarder.cut()


@pytest.fixture
def outage_env(
    stack_env: dict[str, str], pg_schemas: PgSchemas, proxy: TcpProxy
) -> Iterator[dict[str, str]]:
    """A deployment of its own whose database connections all go through ``proxy``."""
    direct = make_url(pg_schemas.new("outage"))
    env = dict(stack_env)
    env.update(FAULT_SETTINGS)
    env["DATABASE_URL"] = direct.set(port=proxy.port).render_as_string(hide_password=False)
    env["TRAJOPT_QUEUE_NAME"] = f"trajopt-outage-{uuid.uuid4().hex[:10]}"
    env["TRAJOPT_RELAY_INTERVAL_S"] = "0.5"
    env["TRAJOPT_RESULT_WRITE_RETRY_S"] = "60"  # a finished result outlives a 15 s outage
    env["DIRECT_DATABASE_URL"] = direct.render_as_string(hide_password=False)
    yield env
    forget_queue(env["REDIS_URL"], env["TRAJOPT_QUEUE_NAME"])


@pytest.fixture
def outage_api(outage_env: dict[str, str], tmp_path: Path) -> Iterator[ApiServer]:
    key = create_api_key(outage_env, "outage")
    yield from ApiServer(outage_env, tmp_path / "api.log", key).serving()


@pytest.fixture
def outage_workers(outage_env: dict[str, str], tmp_path: Path) -> Iterator[Workers]:
    started = Workers(outage_env, tmp_path)
    yield started
    started.stop_all()


def _direct(env: dict[str, str]) -> str:
    return env["DIRECT_DATABASE_URL"]


def test_a_job_stored_but_never_sent_is_sent_by_the_relay(
    outage_env: dict[str, str], outage_api: ApiServer, outage_workers: Workers
) -> None:
    """What an API killed between its commit and its send leaves behind: a stored job that no
    message names. Another (here: the running) API process sends it within seconds."""
    outage_workers.start()
    database = get_database(normalize_database_url(_direct(outage_env)))
    submission = resolve_submission(SMALL)
    with database.session() as session:
        job = repository.create_job(
            session,
            repository.NewJob(
                owner="outage", method=submission.method, problem=submission.document
            ),
        )
    started = time.monotonic()
    found = wait_all_terminal(_direct(outage_env), [job.id], timeout=STRANDED_S + 30)
    assert found[job.id]["attempts"] == 1
    # due after the sender's claim, sent by the next relay, then solved (about a second)
    assert time.monotonic() - started < repository.DISPATCH_CLAIM_S + 15


def test_kill_9_of_the_api_during_a_burst_strands_no_job(
    outage_env: dict[str, str], outage_api: ApiServer, outage_workers: Workers
) -> None:
    outage_workers.start()
    client = outage_api.client()
    accepted: list[str] = []
    refused: list[int] = []

    def submit_all() -> None:
        for _ in range(16):
            try:
                response = client.http.post("/v1/jobs", json=SMALL, timeout=10)
            except Exception:
                continue  # the API died under this request: its job may or may not be stored
            if response.status_code == 202:
                accepted.append(response.json()["id"])
            else:
                refused.append(response.status_code)

    burst = threading.Thread(target=submit_all)
    burst.start()
    deadline = time.monotonic() + 30
    while len(accepted) < 5 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert outage_api.process is not None
    os.killpg(outage_api.process.pid, signal.SIGKILL)
    burst.join(timeout=60)
    client.close()
    outage_api.stop()
    outage_api.start_and_wait()
    back = time.monotonic()

    with get_database(normalize_database_url(_direct(outage_env))).reader() as session:
        stored, _ = repository.list_jobs(session, "outage", None, 100, 0)
    ids = [job.id for job in stored]  # accepted, and any stored whose 202 never went out
    assert set(accepted) <= set(ids) and len(ids) >= 5
    found = wait_all_terminal(_direct(outage_env), ids, timeout=STRANDED_S + 2.0 * len(ids))
    assert time.monotonic() - back < STRANDED_S + 2.0 * len(ids)
    assert_counts(found, ids, outage_workers)
    assert refused == []


def test_a_database_outage_loses_neither_running_nor_queued_jobs(
    outage_env: dict[str, str],
    outage_api: ApiServer,
    outage_workers: Workers,
    proxy: TcpProxy,
) -> None:
    outage_workers.start()
    client = outage_api.client()
    try:
        running = client.submit({"scenario": SCENARIO})  # about 3 s: it ends during the outage
        queued = [client.submit(SMALL)["id"] for _ in range(3)]
        wait_for_row(_direct(outage_env), running["id"], lambda r: r["status"] == "running", 60)
        proxy.cut()
        time.sleep(15.0)
        proxy.restore()
        back = time.monotonic()
        ids = [running["id"], *queued]
        found = wait_all_terminal(_direct(outage_env), ids, timeout=STRANDED_S + 20)
        assert time.monotonic() - back < STRANDED_S + 20
        assert found[running["id"]]["status"] == "succeeded"
        assert found[running["id"]]["attempts"] == 1  # its finished result was kept, not rerun
        assert_counts(found, ids, outage_workers)
        assert "keeping the succeeded result" in outage_workers.log_text()
    finally:
        client.close()


def test_a_worker_lost_near_its_time_limit_is_retried(
    outage_env: dict[str, str], outage_api: ApiServer, outage_workers: Workers
) -> None:
    """Killed after about 3 s of its 20 s wall-clock limit (5 CPU s): the time it ran counts,
    not the time it took to notice, so the job gets a second attempt, which ends at its own
    CPU-time limit."""
    worker = outage_workers.start()
    client = outage_api.client()
    try:
        body: dict[str, Any] = long_job(SCENARIO)
        body["method"]["time_limit_s"] = 5.0
        job = client.submit(body)
        client.wait_for(
            job["id"],
            lambda j: j["status"] == "running" and (j["progress"] or {}).get("elapsed_s", 0) >= 3,
            60,
            "three seconds of iterations",
        )
        kill_children(worker)
        done = client.wait_finished(job["id"], timeout=90)
        assert (done["status"], done["attempts"]) == ("timed_out", 2)
        assert done["error"]["code"] == "time_limit"
        message = done["error"]["message"]  # the worker's stop, or the method's own
        assert "stopped at the job's CPU time limit of 5 s" in message or (
            message.startswith("CPU time limit 5 s reached after")
        ), message
        assert rows(_direct(outage_env), [job["id"]])[job["id"]]["history"] >= 1
        assert done["status"] in TERMINAL
    finally:
        client.close()


def test_a_result_held_through_an_outage_outlives_the_jobs_hard_time_limit(
    outage_env: dict[str, str],
    outage_api: ApiServer,
    outage_workers: Workers,
    proxy: TcpProxy,
) -> None:
    """A job with a 2.5 s CPU-time limit, so a 10 s wall-clock limit: a solve still running at
    12 s (the limit and both 1 s margins) is killed, but this one finishes in a few seconds
    while the database is away, and its worker keeps the result past those 12 s until the
    database is back, at 18 s: one attempt, its outcome stored (``succeeded``; ``timed_out`` by
    its own limit when 2.5 CPU seconds do not solve it)."""
    outage_workers.start()
    client = outage_api.client()
    try:
        job = client.submit({"scenario": SCENARIO, "method": {"time_limit_s": 2.5}})["id"]
        wait_for_row(_direct(outage_env), job, lambda r: r["status"] == "running", 60)
        started = time.monotonic() - _running_for(_direct(outage_env), job)
        proxy.cut()
        time.sleep(max(0.0, started + 18.0 - time.monotonic()))
        proxy.restore()
        found = wait_all_terminal(_direct(outage_env), [job], timeout=60)
        assert found[job]["attempts"] == 1, found
        assert found[job]["status"] in ("succeeded", "timed_out") and found[job]["result"]
        assert_counts(found, [job], outage_workers)
        log = outage_workers.log_text()
        assert f"keeping the {found[job]['status']} result" in log
        assert "Hard time limit" not in log and "exited with 'signal" not in log
    finally:
        client.close()


@pytest.fixture
def outage_outlasting_lease(outage_env: dict[str, str]) -> None:
    """A lease of 20 s (renewed every 6.7 s) for this deployment, so an 8 s outage cannot
    expire it: with the 2 s of the fault settings the API's sweeper, reconnected first, may
    requeue the job the worker is still solving, a race this test is not about."""
    outage_env["TRAJOPT_LEASE_S"] = "20"


def test_a_worker_logs_a_database_outage_in_a_few_lines(
    outage_outlasting_lease: None,
    outage_env: dict[str, str],
    outage_api: ApiServer,
    outage_workers: Workers,
    proxy: TcpProxy,
) -> None:
    """A job iterating through an 8 s outage: its worker logs the first failure of each loop
    (the attempt's writes and reads, its lease heartbeat) with a traceback, then one line at
    growing intervals, and one when the database answers again; not a traceback per retry."""
    worker = outage_workers.start()
    client = outage_api.client()
    try:
        job = client.submit(long_job(SCENARIO))["id"]
        wait_for_row(_direct(outage_env), job, running_with_progress, 60)
        before = rows(_direct(outage_env), [job])[job]["history"]
        proxy.cut()
        time.sleep(8.0)
        proxy.restore()
        wait_for_row(_direct(outage_env), job, lambda r: r["history"] > before + 20, 60)
        assert client.http.delete(f"/v1/jobs/{job}").status_code == 202
        wait_all_terminal(_direct(outage_env), [job], timeout=60)
    finally:
        client.close()
    log = worker.log_text()
    lines = [line for line in log.splitlines() if f"job {job}:" in line]
    failing = [line for line in lines if "could not" in line or "still failing" in line]
    iterations = rows(_direct(outage_env), [job])[job]["history"]
    assert iterations > before + 20  # it iterated through the outage: many retries
    assert 2 <= len(failing) <= 16, failing
    assert _logged_tracebacks(log) <= 2, log[-4000:]
    assert any("answers again" in line or "renewed again" in line for line in lines)


def _logged_tracebacks(log: str) -> int:
    """How many log records carry a traceback (a chained exception prints several
    ``Traceback`` headers under one record)."""
    lines = log.splitlines()
    return sum(
        1
        for previous, line in itertools.pairwise(lines)
        if line.startswith("Traceback") and previous.startswith("[")
    )
