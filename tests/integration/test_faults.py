"""Fault tests: real Celery workers killed by signal, duplicate deliveries, a runaway solve, and
a Redis restart, against real PostgreSQL and Redis. Each test asserts counts: every accepted job
ends terminal, each finished job stored exactly one outcome, and none is left queued or running.

The deployment here uses short leases (2 s, swept every 0.5 s), short Celery margins and a short
hold of a finished result (4 s) so lost workers are noticed, and a frozen one killed, in seconds
rather than the production defaults' tens of seconds or minutes.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import psycopg
import pytest
import redis
from celery import Celery

from tests.integration.conftest import PgSchemas
from tests.integration.harness import (
    SCENARIO,
    TERMINAL,
    ApiServer,
    ServiceClient,
    ServiceProcess,
    create_api_key,
    forget_queue,
    free_port,
    long_job,
)
from worker.celery_app import TASK_NAME, priority_lists

pytestmark = pytest.mark.slow

FAULT_SETTINGS = {
    "TRAJOPT_LEASE_S": "2",
    "TRAJOPT_SWEEP_INTERVAL_S": "0.5",
    "TRAJOPT_SOFT_LIMIT_MARGIN_S": "1",
    "TRAJOPT_HARD_LIMIT_GRACE_S": "1",
    "TRAJOPT_MAX_ATTEMPTS": "3",
    "TRAJOPT_RESULT_WRITE_RETRY_S": "4",
}
SMALL = {"scenario": SCENARIO, "method": {"nodes": 41, "max_iterations": 8}}
"""A job of about a second; it ends succeeded or failed, both terminal."""
UNACKED_KEY, UNACKED_INDEX_KEY = "unacked", "unacked_index"
"""kombu's Redis keys of the messages delivered to a worker and not yet acknowledged."""
STORED_RE = re.compile(r"job ([0-9a-f-]{36}): attempt (\d+) stored outcome (\w+)")


class Workers:
    """Celery worker processes of one test, each with its own log; all stopped at the end."""

    def __init__(self, env: dict[str, str], logs: Path) -> None:
        self.env = env
        self.logs = logs
        self.started: list[ServiceProcess] = []

    def start(self, concurrency: int = 1) -> ServiceProcess:
        log = self.logs / f"worker-{len(self.started)}.log"
        process = ServiceProcess(
            ["-m", "app.cli", "worker", "--concurrency", str(concurrency)], self.env, log
        )
        process.start()
        self.started.append(process)
        process.wait_for_output(" ready.", timeout=90)
        return process

    def log_text(self) -> str:
        return "\n".join(p.log_text() for p in self.started)

    def stored_outcomes(self) -> dict[str, int]:
        """How many attempts stored an outcome, per job id, over every worker's log."""
        counts: dict[str, int] = {}
        for match in STORED_RE.finditer(self.log_text()):
            counts[match.group(1)] = counts.get(match.group(1), 0) + 1
        return counts

    def stop_all(self) -> None:
        for process in self.started:
            process.stop()


def pool_children(worker: ServiceProcess) -> list[int]:
    """Process ids of a worker's pool processes."""
    assert worker.process is not None
    out = subprocess.run(
        ["pgrep", "-P", str(worker.process.pid)], capture_output=True, text=True, check=False
    )
    return [int(pid) for pid in out.stdout.split()]


def kill_children(worker: ServiceProcess, sig: int = signal.SIGKILL) -> list[int]:
    children = pool_children(worker)
    assert children, "the worker has no pool process"
    for pid in children:
        os.kill(pid, sig)
    return children


def rows(database_url: str, ids: list[str]) -> dict[str, dict[str, Any]]:
    """status, attempts, whether a result is stored, history length and error code per job."""
    with psycopg.connect(database_url) as conn:
        found = conn.execute(
            "SELECT id, status, attempts, result IS NOT NULL, jsonb_array_length(history), "
            "error_code FROM jobs WHERE id = ANY(%s)",
            (ids,),
        ).fetchall()
    return {
        r[0]: {"status": r[1], "attempts": r[2], "result": r[3], "history": r[4], "error": r[5]}
        for r in found
    }


def wait_all_terminal(database_url: str, ids: list[str], timeout: float) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while True:
        found = rows(database_url, ids)
        if len(found) == len(ids) and all(r["status"] in TERMINAL for r in found.values()):
            return found
        if time.monotonic() > deadline:
            pytest.fail(f"not all jobs terminal after {timeout} s: {found}")
        time.sleep(0.2)


LOG_GRACE_S = 10.0
"""How long the stored-outcome log lines may trail the rows: a worker commits the outcome, stops
the attempt's heartbeat thread, then logs (a fast job's row can be read before its line)."""


def assert_counts(found: dict[str, Any], ids: list[str], workers: Workers) -> None:
    """accepted = terminal; one stored outcome per job; a result for every succeeded job."""
    assert sorted(found) == sorted(ids)
    assert all(r["status"] in TERMINAL for r in found.values()), found
    by_worker = [
        job_id for job_id, row in found.items() if row["error"] not in ("worker_lost", "time_limit")
    ]
    deadline = time.monotonic() + LOG_GRACE_S
    stored = workers.stored_outcomes()
    while any(j not in stored for j in by_worker) and time.monotonic() < deadline:
        time.sleep(0.1)
        stored = workers.stored_outcomes()
    for job_id, row in found.items():
        if row["error"] in ("worker_lost", "time_limit") and stored.get(job_id, 0) == 0:
            continue  # ended by the service's sweeper, no worker stored it
        assert stored.get(job_id) == 1, (job_id, row, stored.get(job_id))
        if row["status"] == "succeeded":
            assert row["result"], job_id


def wait_for_row(
    database_url: str, job_id: str, predicate: Callable[[dict[str, Any]], bool], timeout: float
) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while True:
        row = rows(database_url, [job_id]).get(job_id)
        if row is not None and predicate(row):
            return row
        if time.monotonic() > deadline:
            pytest.fail(f"job {job_id}: condition not reached in {timeout} s; last {row}")
        time.sleep(0.1)


def running_with_progress(row: dict[str, Any]) -> bool:
    return bool(row["status"] == "running" and row["history"] and row["history"] >= 1)


@pytest.fixture(scope="module")
def fault_env(stack_env: dict[str, str], pg_schemas: PgSchemas) -> Iterator[dict[str, str]]:
    """A deployment of its own: schema, queue, short leases and Celery margins."""
    env = dict(stack_env)
    env.update(FAULT_SETTINGS)
    env["DATABASE_URL"] = pg_schemas.new("faults")
    env["TRAJOPT_QUEUE_NAME"] = f"trajopt-faults-{uuid.uuid4().hex[:10]}"
    yield env
    forget_queue(env["REDIS_URL"], env["TRAJOPT_QUEUE_NAME"])


@pytest.fixture(scope="module")
def fault_api(
    fault_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory
) -> Iterator[ApiServer]:
    key = create_api_key(fault_env, "faults")
    yield from ApiServer(
        fault_env, tmp_path_factory.mktemp("fault-logs") / "api.log", key
    ).serving()


@pytest.fixture
def fault_client(fault_api: ApiServer) -> Iterator[ServiceClient]:
    yield from fault_api.serving_client()


@pytest.fixture
def workers(fault_env: dict[str, str], tmp_path: Path) -> Iterator[Workers]:
    started = Workers(fault_env, tmp_path)
    yield started
    started.stop_all()


def test_kill_9_of_a_pool_process_and_of_a_whole_worker_loses_nothing(
    fault_env: dict[str, str], fault_client: ServiceClient, workers: Workers
) -> None:
    db = fault_env["DATABASE_URL"]
    first = workers.start()
    ids = [fault_client.submit({"scenario": SCENARIO})["id"]]
    ids += [fault_client.submit(SMALL)["id"] for _ in range(3)]
    wait_for_row(db, ids[0], running_with_progress, 60)
    kill_children(first)  # the pool process dies mid-solve
    # The job is re-queued by the sweeper once its lease lapses, then runs again.
    wait_for_row(db, ids[0], lambda r: r["attempts"] >= 2 and running_with_progress(r), 60)
    assert first.process is not None
    os.killpg(first.process.pid, signal.SIGKILL)  # now the whole worker, mid-solve
    first.process.wait(timeout=10)
    time.sleep(1.0)
    workers.start()  # a replacement worker
    found = wait_all_terminal(db, ids, timeout=150)
    assert found[ids[0]]["status"] == "succeeded"
    assert found[ids[0]]["attempts"] >= 3  # started three times, stored once
    assert_counts(found, ids, workers)


def test_a_poison_job_fails_after_the_cap_without_blocking_the_queue(
    fault_env: dict[str, str], fault_client: ServiceClient, workers: Workers
) -> None:
    db = fault_env["DATABASE_URL"]
    worker = workers.start()
    poison = fault_client.submit(long_job(SCENARIO))["id"]
    others = [fault_client.submit(SMALL)["id"] for _ in range(2)]
    stop = threading.Event()
    kills: list[int] = []

    def crash_whenever_the_poison_runs() -> None:  # the job "always crashes its worker"
        while not stop.is_set():
            row = rows(db, [poison]).get(poison)
            if row and row["status"] == "running" and row["attempts"] not in kills:
                kills.append(row["attempts"])
                kill_children(worker)
            time.sleep(0.05)

    watcher = threading.Thread(target=crash_whenever_the_poison_runs, daemon=True)
    watcher.start()
    try:
        found = wait_all_terminal(db, [poison, *others], timeout=180)
    finally:
        stop.set()
        watcher.join(timeout=5)
    assert found[poison]["status"] == "failed"
    assert (found[poison]["error"], found[poison]["attempts"]) == ("worker_lost", 3)
    assert kills == [1, 2, 3]
    for job_id in others:
        assert found[job_id]["attempts"] == 1
    assert_counts(found, [poison, *others], workers)
    assert worker.alive()


def test_duplicate_deliveries_run_one_solve_and_store_one_result(
    fault_env: dict[str, str], fault_client: ServiceClient, workers: Workers
) -> None:
    db = fault_env["DATABASE_URL"]
    workers.start(concurrency=2)  # a second pool process is free to take the duplicates
    celery = Celery(broker=fault_env["REDIS_URL"])

    def deliver_again(job_id: str) -> None:
        celery.send_task(TASK_NAME, args=[job_id], queue=fault_env["TRAJOPT_QUEUE_NAME"])

    job_id = fault_client.submit({"scenario": SCENARIO})["id"]
    wait_for_row(db, job_id, running_with_progress, 60)
    for _ in range(3):
        deliver_again(job_id)
    found = wait_all_terminal(db, [job_id], timeout=120)
    deliver_again(job_id)  # and once more after it finished
    deadline = time.monotonic() + 30
    while workers.log_text().count(f"job {job_id} not run") < 4:
        assert time.monotonic() < deadline, workers.log_text()[-3000:]
        time.sleep(0.2)
    log = workers.log_text()
    assert log.count(f"job {job_id} not run: busy") == 3
    assert log.count(f"job {job_id} not run: finished") == 1
    assert found[job_id]["attempts"] == 1
    assert rows(db, [job_id]) == found  # the late duplicate changed nothing
    assert_counts(found, [job_id], workers)
    celery.close()


def _sent(database_url: str, job_id: str) -> bool:
    """Whether the job is queued, never started and marked sent (its outbox entry closed)."""
    with psycopg.connect(database_url) as conn:
        row = conn.execute(
            "SELECT status, attempts, dispatch_due_at IS NULL FROM jobs WHERE id = %s", (job_id,)
        ).fetchone()
    return row == ("queued", 0, True)


def _take_message(env: dict[str, str], job_id: str) -> bytes:
    """Remove the job's message from the queue's lists and return it (raw)."""
    client = redis.Redis.from_url(env["REDIS_URL"])
    try:
        for name in priority_lists(env["TRAJOPT_QUEUE_NAME"]):
            for raw in client.lrange(name, 0, -1):
                if job_id.encode() in raw and client.lrem(name, 1, raw) == 1:
                    return bytes(raw)
    finally:
        client.close()
    raise AssertionError(f"no message of job {job_id} in the queue")


def test_a_job_whose_message_a_dying_worker_took_is_sent_again_within_a_lease(
    fault_env: dict[str, str], fault_client: ServiceClient, workers: Workers
) -> None:
    """What a worker killed while taking a message leaves behind, made without a kill race:
    a job queued, marked sent, never started, whose message is nowhere (popped from the list,
    never recorded as delivered), and one whose message was recorded as delivered a minute
    ago by a worker that never claimed the job. The API sends both again within about a
    lease, and a late copy of a message (a duplicate delivery) changes nothing."""
    db = fault_env["DATABASE_URL"]
    popped, recorded = (fault_client.submit(SMALL)["id"] for _ in range(2))
    for job_id in (popped, recorded):
        wait_for_row(db, job_id, lambda r, j=job_id: _sent(db, j), 30)
    lost = _take_message(fault_env, popped)
    delivered = json.loads(_take_message(fault_env, recorded))
    tag = f"lost-{uuid.uuid4().hex}"
    broker = redis.Redis.from_url(fault_env["REDIS_URL"])
    broker.hset(UNACKED_KEY, tag, json.dumps([delivered, "", fault_env["TRAJOPT_QUEUE_NAME"]]))
    broker.zadd(UNACKED_INDEX_KEY, {tag: time.time() - 60.0})
    try:
        workers.start()
        ready = time.monotonic()
        found = wait_all_terminal(db, [popped, recorded], timeout=30)
        assert time.monotonic() - ready < 3 * float(FAULT_SETTINGS["TRAJOPT_LEASE_S"]) + 10
        assert {row["attempts"] for row in found.values()} == {1}
        assert_counts(found, [popped, recorded], workers)
        broker.lpush(fault_env["TRAJOPT_QUEUE_NAME"], lost)  # the lost message, late
        deadline = time.monotonic() + 30
        while f"job {popped} not run: finished" not in workers.log_text():
            assert time.monotonic() < deadline, workers.log_text()[-3000:]
            time.sleep(0.2)
        assert rows(db, [popped, recorded]) == found
    finally:
        broker.hdel(UNACKED_KEY, tag)
        broker.zrem(UNACKED_INDEX_KEY, tag)
        broker.close()


def test_the_hard_time_limit_ends_a_runaway_solve_and_the_worker_goes_on(
    fault_env: dict[str, str], fault_client: ServiceClient, workers: Workers
) -> None:
    db = fault_env["DATABASE_URL"]
    worker = workers.start()
    body = long_job(SCENARIO)
    body["method"]["time_limit_s"] = 3.0  # CPU s: wall 12 s, soft 13 s, hard 18 s here
    runaway = fault_client.submit(body)["id"]
    wait_for_row(db, runaway, running_with_progress, 60)
    # Stopped at 1.8 s: it never returns and ignores signals. Its lease (2 s) lapses long
    # before the hard limit (the 12 s wall-clock limit, both margins and the 4 s result hold:
    # 18 s) kills it; it had run 1.8 s, under its limit, so it is re-queued (only the time an
    # attempt ran counts), and its second attempt ends at its own limit.
    while _running_for(db, runaway) < 1.8:
        time.sleep(0.05)
    stopped = kill_children(worker, signal.SIGSTOP)
    found = wait_all_terminal(db, [runaway], timeout=90)
    assert found[runaway]["status"] == "timed_out"
    assert found[runaway]["error"] == "time_limit"
    assert found[runaway]["attempts"] == 2
    assert found[runaway]["history"] >= 1  # the history so far is kept
    for pid in stopped:  # the hard limit killed the stopped process
        deadline = time.monotonic() + 30
        while Path(f"/proc/{pid}").exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not Path(f"/proc/{pid}").exists() or "Z" in _proc_state(pid)
    following = fault_client.submit(SMALL)["id"]
    done = wait_all_terminal(db, [following], timeout=90)
    assert done[following]["attempts"] == 1
    assert worker.alive()  # the same worker, with a fresh pool process
    assert_counts({**found, **done}, [runaway, following], workers)


def _running_for(database_url: str, job_id: str) -> float:
    with psycopg.connect(database_url) as conn:
        row = conn.execute(
            "SELECT EXTRACT(EPOCH FROM (now() - started_at)) FROM jobs WHERE id = %s", (job_id,)
        ).fetchone()
    return float(row[0]) if row and row[0] is not None else 0.0


def _proc_state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2]
    except OSError:
        return "gone"


class OwnRedis:
    """A redis-server of this test on a free loopback port, with an append-only file."""

    def __init__(self, folder: Path) -> None:
        self.port = free_port()
        self.folder = folder
        self.process: subprocess.Popen[bytes] | None = None

    @property
    def url(self) -> str:
        return f"redis://127.0.0.1:{self.port}/0"

    def start(self) -> None:
        args = [
            "redis-server", "--port", str(self.port), "--bind", "127.0.0.1",
            "--dir", str(self.folder), "--appendonly", "yes", "--appendfsync", "always",
            "--save", "", "--protected-mode", "yes",
        ]  # fmt: skip
        log = (self.folder / "redis.log").open("ab")
        self.process = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT)
        import redis

        deadline = time.monotonic() + 10
        while True:
            try:
                redis.Redis.from_url(self.url, socket_connect_timeout=0.5).ping()
                return
            except redis.RedisError:
                assert time.monotonic() < deadline, "own redis-server did not start"
                time.sleep(0.1)

    def stop(self) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.terminate()
            self.process.wait(timeout=10)


def test_redis_restart_loses_no_accepted_job_and_outage_submissions_get_503(
    stack_env: dict[str, str], pg_schemas: PgSchemas, tmp_path: Path
) -> None:
    own = OwnRedis(tmp_path)
    own.start()
    env = {**stack_env, **FAULT_SETTINGS, "REDIS_URL": own.url}
    env["DATABASE_URL"] = pg_schemas.new("redis_restart")
    env["TRAJOPT_QUEUE_NAME"] = "trajopt-restart"
    db = env["DATABASE_URL"]
    workers = Workers(env, tmp_path)
    api = ApiServer(env, tmp_path / "api.log", create_api_key(env, "restart"))
    try:
        worker = workers.start()
        api.start_and_wait()
        client = api.client()
        ids = [client.submit({"scenario": SCENARIO})["id"]]
        ids += [client.submit(SMALL)["id"] for _ in range(3)]
        wait_for_row(db, ids[0], running_with_progress, 60)

        own.stop()  # the broker goes away with one job running and three queued
        outage = [client.http.post("/v1/jobs", json=SMALL) for _ in range(3)]
        assert [r.status_code for r in outage] == [503] * 3
        assert all(int(r.headers["retry-after"]) >= 1 for r in outage)
        assert {r.json()["error"]["code"] for r in outage} == {"queue_unavailable"}
        assert client.http.get(f"/v1/jobs/{ids[1]}").status_code == 200  # reads still work
        assert client.http.get("/readyz").status_code == 503
        time.sleep(3.0)

        own.start()  # same port, same append-only file
        found = wait_all_terminal(db, ids, timeout=180)
        after = client.submit(SMALL)["id"]  # the worker reconnected by itself
        found.update(wait_all_terminal(db, [after], timeout=90))
        assert worker.alive()
        listed = client.http.get("/v1/jobs", params={"limit": 100}).json()
        assert listed["total"] == len(ids) + 1  # the refused submissions left nothing behind
        assert_counts(found, [*ids, after], workers)
        client.close()
    finally:
        api.stop()
        workers.stop_all()
        own.stop()
