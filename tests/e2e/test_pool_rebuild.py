"""A pool process of the embedded server killed mid-solve: the pool is rebuilt, the job goes
back to the queue at once (its holder is gone) and runs again, and the server goes on."""

from __future__ import annotations

import os
import signal
import sqlite3
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.integration.harness import (
    SCENARIO,
    ApiServer,
    ServiceClient,
    embedded_env,
    long_job,
)

pytestmark = pytest.mark.slow


def _iterating(job: dict[str, Any]) -> bool:
    return job["status"] == "running" and (job["progress"] or {}).get("iteration", 0) >= 1


@pytest.fixture
def server(tmp_path: Path) -> Iterator[ApiServer]:
    yield from ApiServer(embedded_env(tmp_path), tmp_path / "serve.log").serving()


def _holder_pid(data_dir: Path, job_id: str) -> int:
    with sqlite3.connect(data_dir / "trajopt.sqlite3") as conn:
        (holder,) = conn.execute("SELECT lease_holder FROM jobs WHERE id = ?", (job_id,)).fetchone()
    return int(str(holder).rpartition("/")[2])


def test_a_killed_pool_process_is_replaced_and_its_job_runs_again(
    server: ApiServer, tmp_path: Path
) -> None:
    client: ServiceClient = server.client()
    try:
        job = client.submit(long_job(SCENARIO))
        client.wait_for(job["id"], _iterating, 60, "first iteration")
        os.kill(_holder_pid(tmp_path, job["id"]), signal.SIGKILL)
        again = client.wait_for(
            job["id"], lambda j: j["attempts"] == 2 and _iterating(j), 60, "second attempt"
        )
        assert again["status"] == "running"
        assert client.http.delete(f"/v1/jobs/{job['id']}").status_code == 202
        assert client.wait_finished(job["id"], timeout=30)["status"] == "cancelled"
        after = client.submit({"scenario": SCENARIO})
        assert client.wait_finished(after["id"])["status"] == "succeeded"
        assert "restarting the local pool" in server.log_text()
        assert "Traceback" not in server.log_text()
    finally:
        client.close()
