"""Two ``trajopt serve`` processes on one embedded database: neither takes the other's running
job, a second one on a port in use fails before touching anything, and a job of a server that
stops is taken over by the other one within a sweep.
"""

from __future__ import annotations

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
