"""Event-stream caps and their cost, on a real uvicorn API in api-keys mode over PostgreSQL,
Redis and a Celery worker: over a cap a stream is 429 with Retry-After, another client's reads
stay fast while one client holds 300 streams, and those streams add no per-stream queries."""

from __future__ import annotations

import statistics
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import httpx
import psycopg
import pytest

from tests.integration.harness import (
    REPO_ROOT,
    ApiServer,
    ServiceClient,
    ServiceProcess,
    create_api_key,
    forget_queue,
    long_job,
)

pytestmark = pytest.mark.slow

STREAMS = 300


def stream_server(env: dict[str, str], log: Path, **settings: str) -> ApiServer:
    """A started API server of this run's stack with ``settings`` on top."""
    server = ApiServer({**env, **settings}, log)
    server.start_and_wait()
    return server


def running(client: ServiceClient, job: dict[str, Any]) -> dict[str, Any]:
    """Wait until the job runs and has iterated (it then streams events continuously)."""
    return client.wait_for(
        job["id"], lambda j: j["status"] == "running" and bool(j["progress"]), 180, "running"
    )


def open_stream(stack: ExitStack, client: ServiceClient, job_id: str) -> httpx.Response:
    """Open the job's event stream (closed with ``stack``) and return its response head."""
    return stack.enter_context(client.http.stream("GET", f"/v1/jobs/{job_id}/events"))


def test_stream_caps_per_client_and_in_total_refuse_with_retry_after(
    stack_env: dict[str, str], worker: ServiceProcess, scenario: str, tmp_path: Path
) -> None:
    server = stream_server(
        stack_env,
        tmp_path / "api.log",
        TRAJOPT_MAX_STREAMS="5",
        TRAJOPT_MAX_STREAMS_PER_CLIENT="3",
    )
    a = ServiceClient(server.base_url, create_api_key(stack_env, "caps-a"))
    b = ServiceClient(server.base_url, create_api_key(stack_env, "caps-b"))
    jobs: list[tuple[ServiceClient, str]] = []
    try:
        job_a = a.submit(long_job(scenario))
        job_b = b.submit(long_job(scenario))  # queued behind A's: its stream stays open too
        jobs += [(a, job_a["id"]), (b, job_b["id"])]
        with ExitStack() as a_streams, ExitStack() as b_streams:
            for _ in range(3):
                assert open_stream(a_streams, a, job_a["id"]).status_code == 200
            refused = a.http.get(f"/v1/jobs/{job_a['id']}/events")
            assert refused.status_code == 429, refused.text
            assert refused.headers["retry-after"] == "5"
            error = refused.json()["error"]
            assert error["code"] == "too_many_streams"
            assert (
                "3 event streams open, at most 3 (TRAJOPT_MAX_STREAMS_PER_CLIENT)"
                in (error["message"])
            )
            for _ in range(2):
                assert open_stream(b_streams, b, job_b["id"]).status_code == 200
            full = b.http.get(f"/v1/jobs/{job_b['id']}/events")
            assert full.status_code == 429, full.text
            assert full.headers["retry-after"] == "5"
            assert (
                "5 event streams open, at most 5 (TRAJOPT_MAX_STREAMS)"
                in (full.json()["error"]["message"])
            )
            # an unknown job is refused the same way at the cap: the cap says nothing of jobs
            assert a.http.get(f"/v1/jobs/{uuid.uuid4()}/events").status_code == 429

            a_streams.close()  # A closes its three streams: the server notices and frees them
            deadline = time.monotonic() + 10
            while True:
                with a.http.stream("GET", f"/v1/jobs/{job_a['id']}/events") as again:
                    if again.status_code == 200:
                        break
                assert again.status_code == 429
                assert time.monotonic() < deadline, "closed streams were not released"
                time.sleep(0.1)
        assert "Traceback" not in server.log_text()
    finally:
        for client, job_id in jobs:
            client.http.delete(f"/v1/jobs/{job_id}")
        a.close()
        b.close()
        server.stop()


class Holder:
    """The stream holder process: one client's ``count`` streams of one job."""

    def __init__(self, server: ApiServer, key: str, job_id: str, count: int, log: Path) -> None:
        self.log = log
        self._out = log.open("w", encoding="utf-8")
        self.process = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "tests.integration.stream_holder",
                server.base_url,
                key,
                job_id,
                str(count),
            ],
            cwd=REPO_ROOT,
            stdout=self._out,
            stderr=subprocess.STDOUT,
        )

    def lines(self) -> list[str]:
        """What the holder printed so far."""
        return self.log.read_text(encoding="utf-8").splitlines()

    def wait_open(self, timeout: float = 60.0) -> str:
        """Wait until every stream has its response head; returns the ``opened`` line."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            opened = [line for line in self.lines() if line.startswith("opened")]
            if opened:
                return opened[0]
            assert self.process.poll() is None, "\n".join(self.lines())
            time.sleep(0.1)
        pytest.fail("the streams did not open:\n" + "\n".join(self.lines()))

    def received(self) -> int:
        """Bytes all streams received so far (as last reported)."""
        counts = [int(line.split()[1]) for line in self.lines() if line.startswith("bytes")]
        return counts[-1] if counts else 0

    def stop(self) -> None:
        """Stop the holder (its streams close with it)."""
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(timeout=10)
        self._out.close()


def read_latencies(client: ServiceClient, count: int) -> list[float]:
    """Seconds of ``count`` sequential ``GET /v1/jobs`` of ``client``."""
    times = []
    for _ in range(count):
        start = time.perf_counter()
        response = client.http.get("/v1/jobs")
        times.append(time.perf_counter() - start)
        assert response.status_code == 200, response.text
    return times


def p95(times: list[float]) -> float:
    """The 95th percentile."""
    return statistics.quantiles(times, n=20)[-1]


@pytest.fixture
def many_streams_server(stack_env: dict[str, str], tmp_path: Path) -> Iterator[ApiServer]:
    """An API whose caps admit one client's 300 streams."""
    server = stream_server(
        stack_env,
        tmp_path / "api.log",
        TRAJOPT_MAX_STREAMS=str(STREAMS + 20),
        TRAJOPT_MAX_STREAMS_PER_CLIENT=str(STREAMS),
    )
    try:
        yield server
    finally:
        server.stop()


@pytest.mark.exclusive
def test_another_clients_reads_stay_fast_while_one_client_holds_300_streams(
    many_streams_server: ApiServer,
    stack_env: dict[str, str],
    worker: ServiceProcess,
    scenario: str,
    tmp_path: Path,
) -> None:
    server = many_streams_server
    key_a = create_api_key(stack_env, "load-a")
    a = ServiceClient(server.base_url, key_a)
    b = ServiceClient(server.base_url, create_api_key(stack_env, "load-b"))
    holder: Holder | None = None
    job = a.submit(long_job(scenario))  # iterates for a minute: every stream gets events
    try:
        running(a, job)
        read_latencies(b, 10)  # warm the connection and the server's caches
        idle = read_latencies(b, 100)
        holder = Holder(server, key_a, job["id"], STREAMS, tmp_path / "holder.log")
        assert holder.wait_open() == f"opened {STREAMS} refused 0"
        time.sleep(1.0)
        before = holder.received()
        loaded = read_latencies(b, 200)
        time.sleep(1.1)
        flowed = holder.received() - before
        median = statistics.median(loaded) * 1000
        print(
            f"GET /v1/jobs p95: {p95(idle) * 1000:.1f} ms with no streams, "
            f"{p95(loaded) * 1000:.1f} ms with {STREAMS} (p50 {median:.1f} ms); "
            f"the streams received {flowed} bytes meanwhile"
        )
        assert a.job(job["id"])["status"] == "running"
        assert flowed > STREAMS * 200, "the streams were not receiving iteration events"
        # The bar of the issue: p95 <= 100 ms on this shared 2-core machine, where the API,
        # the worker solving the job, PostgreSQL, Redis and the 300-stream client all compete
        # for the CPUs. Idle reads take ~10-25 ms here; 100 ms leaves room for that contention,
        # while the old per-stream polling measured p50 28.7 s at 300 streams.
        assert p95(loaded) <= 0.100, (p95(idle), p95(loaded))
        assert "Traceback" not in server.log_text()
    finally:
        if holder is not None:
            holder.stop()
        a.http.delete(f"/v1/jobs/{job['id']}")
        a.wait_finished(job["id"], timeout=60)
        a.close()
        b.close()


def jobs_table_scans(database_url: str) -> int:
    """Index and sequential scans of the ``jobs`` table of this run's schema so far."""
    with psycopg.connect(database_url, autocommit=True) as conn:
        conn.execute("SELECT pg_stat_clear_snapshot()")
        row = conn.execute(
            "SELECT coalesce(idx_scan, 0) + coalesce(seq_scan, 0) FROM pg_stat_user_tables "
            "WHERE relname = 'jobs' AND schemaname = current_schema()"
        ).fetchone()
    assert row is not None
    return int(row[0])


def scans_per_second(database_url: str, seconds: float) -> float:
    """Scans of the jobs table per second over ``seconds`` (PostgreSQL publishes a backend's
    counts about once a second, hence windows of several seconds)."""
    start = jobs_table_scans(database_url)
    time.sleep(seconds)
    return (jobs_table_scans(database_url) - start) / seconds


def test_300_streams_of_an_idle_running_job_add_no_per_stream_queries(
    stack_env: dict[str, str], tmp_path: Path, scenario: str
) -> None:
    # A queue no worker consumes: the job is made running by hand and then nothing changes it.
    queue = f"trajopt-idle-{uuid.uuid4().hex[:10]}"
    env = {**stack_env, "TRAJOPT_QUEUE_NAME": queue}
    server = stream_server(
        env,
        tmp_path / "api.log",
        TRAJOPT_MAX_STREAMS=str(STREAMS),
        TRAJOPT_MAX_STREAMS_PER_CLIENT=str(STREAMS),
    )
    key = create_api_key(env, "idle")
    client = ServiceClient(server.base_url, key)
    holder: Holder | None = None
    database_url = env["DATABASE_URL"]
    job = client.submit(long_job(scenario))
    try:
        with psycopg.connect(database_url, autocommit=True) as conn:
            conn.execute(
                "UPDATE jobs SET status = 'running', attempts = 1, lease_holder = 'elsewhere/1', "
                "lease_expires_at = now() + interval '1 hour', updated_at = now() WHERE id = %s",
                (job["id"],),
            )
        time.sleep(3.0)  # the submission's own scans reach the counts
        without = scans_per_second(database_url, 6.0)
        holder = Holder(server, key, job["id"], STREAMS, tmp_path / "holder.log")
        assert holder.wait_open() == f"opened {STREAMS} refused 0"
        time.sleep(3.0)  # the 300 admissions' own scans (one per stream) reach the counts
        with_streams = scans_per_second(database_url, 6.0)
        print(
            f"jobs-table scans per second: {without:.1f} with no streams, {with_streams:.1f} "
            f"with {STREAMS} streams of one idle running job"
        )
        # The shared watcher reads an idle job once a second in broker mode (one query for all
        # watched jobs); the sweeper and the outbox relay make the rest of the baseline. The old
        # per-stream loop added one query per stream per second: 300 here. A margin of 3/s
        # covers PostgreSQL's once-a-second publication of the counts.
        assert with_streams - without <= 3.0, (without, with_streams)
        assert "Traceback" not in server.log_text()
    finally:
        if holder is not None:
            holder.stop()
        with psycopg.connect(database_url, autocommit=True) as conn:  # no worker ends it
            conn.execute(
                "UPDATE jobs SET status = 'cancelled', finished_at = now(), updated_at = now() "
                "WHERE id = %s",
                (job["id"],),
            )
        client.close()
        server.stop()
        forget_queue(env["REDIS_URL"], queue)
