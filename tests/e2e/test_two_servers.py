"""Two ``trajopt serve`` processes on one embedded database: neither takes the other's running
job, a second one on a port in use fails before touching anything, and a job of a server that
stops is taken over by the other one within a sweep.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.integration.harness import REPO_ROOT, SCENARIO, ApiServer, long_job, service_free_env

pytestmark = pytest.mark.slow


def _iterating(job: dict[str, Any]) -> bool:
    return job["status"] == "running" and (job["progress"] or {}).get("iteration", 0) >= 1


@pytest.fixture
def env(tmp_path: Path) -> dict[str, str]:
    return service_free_env(TRAJOPT_DATA_DIR=str(tmp_path), TRAJOPT_SWEEP_INTERVAL_S="1")


@pytest.fixture
def first(env: dict[str, str], tmp_path: Path) -> Iterator[ApiServer]:
    yield from ApiServer(env, tmp_path / "first.log").serving()


def test_a_second_server_never_takes_a_live_job(
    first: ApiServer, env: dict[str, str], tmp_path: Path
) -> None:
    client = first.client()
    job = client.submit(long_job(SCENARIO))
    client.wait_for(job["id"], _iterating, 60, "first iteration")

    clash = subprocess.run(
        [sys.executable, "-m", "app.cli", "serve", "--port", str(first.port)],
        cwd=REPO_ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert clash.returncode == 2
    assert "Traceback" not in clash.stderr
    assert f"cannot listen on 127.0.0.1:{first.port}" in clash.stderr
    assert client.job(job["id"])["attempts"] == 1

    second = ApiServer(env, tmp_path / "second.log")
    second.start_and_wait()
    other = second.client()
    try:
        before = client.job(job["id"])["progress"]["iteration"]
        time.sleep(2.0)
        now = other.job(job["id"])
        assert (now["status"], now["attempts"]) == ("running", 1)
        assert now["progress"]["iteration"] > before  # still iterating in the first server

        assert other.http.delete(f"/v1/jobs/{job['id']}").status_code == 202
        done = client.wait_finished(job["id"], timeout=30)
        assert (done["status"], done["attempts"]) == ("cancelled", 1)

        short = other.submit({"scenario": SCENARIO})
        assert other.wait_finished(short["id"])["status"] == "succeeded"

        # a server that stops with a running job: the other takes it over at its next sweep
        handed = client.submit(long_job(SCENARIO))
        client.wait_for(handed["id"], _iterating, 60, "first iteration")
        first.stop()
        taken = other.wait_for(
            handed["id"],
            lambda j: j["attempts"] == 2 and _iterating(j),
            60,
            "second attempt in the other server",
        )
        assert taken["status"] == "running"
        other.http.delete(f"/v1/jobs/{handed['id']}")
        assert other.wait_finished(handed["id"], timeout=30)["status"] == "cancelled"
    finally:
        other.close()
        client.close()
        second.stop()
    for log in (first.log_text(), second.log_text()):
        assert "no longer owns the job" not in log
        assert "Traceback" not in log
        assert "leaked semaphore" not in log


def test_a_killed_servers_queued_and_running_jobs_are_taken_over_within_a_lease(
    tmp_path: Path,
) -> None:
    """``kill -9`` of a server whose pool holds one running job and two queued ones: the
    other server on the same data folder takes the queued ones over at once (the holder's
    process is gone) and the running one once its lease lapses; neither waits for the
    stale-queued resend."""
    lease_s = 5.0
    env = service_free_env(
        TRAJOPT_DATA_DIR=str(tmp_path),
        TRAJOPT_SWEEP_INTERVAL_S="1",
        TRAJOPT_LEASE_S=str(lease_s),
        TRAJOPT_LOCAL_WORKERS="1",
    )
    first, second = ApiServer(env, tmp_path / "first.log"), ApiServer(env, tmp_path / "second.log")
    first.start_and_wait()
    second.start_and_wait()
    client, other = first.client(), second.client()
    try:
        running = client.submit(long_job(SCENARIO))["id"]
        client.wait_for(running, _iterating, 60, "first iteration")
        small = {"scenario": SCENARIO, "method": {"nodes": 41, "max_iterations": 8}}
        queued = [client.submit(small)["id"] for _ in range(2)]
        time.sleep(2.0)  # the live first server keeps them: its pool is busy
        assert [other.job(j)["status"] for j in queued] == ["queued", "queued"]
        assert first.process is not None
        os.kill(first.process.pid, signal.SIGKILL)
        first.process.wait(timeout=10)  # reaped, as its service manager would
        killed = time.monotonic()
        for job_id in queued:
            done = other.wait_finished(job_id, timeout=60)
            assert done["attempts"] == 1
        assert time.monotonic() - killed < lease_s + 15
        taken = other.wait_for(
            running, lambda j: j["attempts"] == 2 and _iterating(j), 60, "second attempt"
        )
        assert taken["status"] == "running"
        assert time.monotonic() - killed < 2 * lease_s + 20
        other.http.delete(f"/v1/jobs/{running}")
        assert other.wait_finished(running, timeout=30)["status"] == "cancelled"
    finally:
        other.close()
        client.close()
        second.stop()
        first.stop()
    assert "taking it over" in second.log_text()
    assert "Traceback" not in second.log_text()
