"""The first start after an install: the embedded pool compiles the solver's kernels before the
service reports ready, and a job submitted meanwhile says what it waits for.

An empty numba cache folder stands for a fresh install (the kernels must be compiled, which
takes tens of seconds here).
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from tests.integration.harness import SCENARIO, ApiServer, service_free_env

pytestmark = pytest.mark.slow


def test_the_service_is_ready_only_after_the_kernels_are_compiled(tmp_path: Path) -> None:
    env = service_free_env()
    cache = tmp_path / "numba-cache"
    env.update(TRAJOPT_DATA_DIR=str(tmp_path / "data"), NUMBA_CACHE_DIR=str(cache))
    server = ApiServer(env, tmp_path / "serve.log")
    server.start()
    client = server.client()
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                first = client.http.get("/readyz")
                break
            except httpx.TransportError:
                assert time.monotonic() < deadline and server.alive(), server.log_text()
                time.sleep(0.1)
        assert first.status_code == 503, first.text
        assert "loading the solver" in first.json()["checks"]["local"]

        job = client.submit({"scenario": SCENARIO})
        waiting = client.job(job["id"])
        assert waiting["status"] == "queued"
        assert waiting["progress"]["phase"] == "compiling"

        events = list(client.events(job["id"], timeout=300))
        phases = [e["data"]["phase"] for e in events if e["event"] == "phase"]
        # the verification takes tens of milliseconds: the stream may see it or not
        assert phases[0] == "compiling" and "optimizing" in phases
        assert set(phases) <= {"compiling", "optimizing", "verifying"}
        assert events[-1]["event"] == "end"
        assert events[-1]["data"]["status"] == "succeeded"
        assert client.http.get("/readyz").status_code == 200
        assert any(cache.rglob("*.nbi"))  # the kernels were compiled into this cache
        assert "solver loaded in the job pool" in server.log_text()
    finally:
        client.close()
        server.stop()


def test_the_command_line_says_when_it_compiles(tmp_path: Path) -> None:
    """``trajopt solve`` on an empty kernel cache says on stderr why it waits; on the filled
    cache it does not."""
    env = service_free_env()
    env.update(TRAJOPT_DATA_DIR=str(tmp_path / "data"), NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    notice = "compiling the solver's kernels"
    runs = []
    for _ in range(2):
        done = subprocess.run(
            [sys.executable, "-m", "app.cli", "solve", SCENARIO, "--quiet"],
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
            check=False,
        )
        assert done.returncode == 0, done.stderr
        runs.append(done.stderr)
    assert notice in runs[0], runs[0]
    assert notice not in runs[1], runs[1]
