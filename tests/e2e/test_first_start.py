"""The first start after an install: the embedded pool compiles the solver's kernels before the
service reports ready, a job submitted meanwhile says what it waits for, and Ctrl+C meanwhile is
an ordinary shutdown.

An empty numba cache folder stands for a fresh install (the kernels must be compiled, which
takes about a minute here).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from tests.integration.harness import (
    SCENARIO,
    ApiServer,
    ServiceClient,
    run_cli,
    service_free_env,
)

pytestmark = pytest.mark.slow

COMPILING = "starting: compiling the solver's kernels"
"""The readiness check's answer while the pool compiles the kernels."""


def _first_start(tmp_path: Path) -> tuple[ApiServer, Path]:
    """A server (not started) on a fresh data folder and an empty numba cache folder."""
    env = service_free_env()
    cache = tmp_path / "numba-cache"
    env.update(TRAJOPT_DATA_DIR=str(tmp_path / "data"), NUMBA_CACHE_DIR=str(cache))
    return ApiServer(env, tmp_path / "serve.log"), cache


def _wait_until_compiling(server: ApiServer, client: ServiceClient) -> None:
    """Block until ``/readyz`` says the pool compiles the kernels (503 all along)."""
    deadline = time.monotonic() + 60
    while True:
        assert time.monotonic() < deadline and server.alive(), server.log_text()
        try:
            answer = client.http.get("/readyz")
        except httpx.TransportError:
            time.sleep(0.1)
            continue
        assert answer.status_code == 503, answer.text
        if answer.json()["checks"]["local"].startswith(COMPILING):
            return
        assert answer.json()["checks"]["local"] == "starting: loading the solver", answer.text
        time.sleep(0.1)


def test_the_service_is_ready_only_after_the_kernels_are_compiled(tmp_path: Path) -> None:
    server, cache = _first_start(tmp_path)
    server.start()
    client = server.client()
    try:
        _wait_until_compiling(server, client)

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


def test_ctrl_c_while_the_pool_compiles_is_a_clean_shutdown(tmp_path: Path) -> None:
    """Ctrl+C (SIGINT to the server's process group) during the first start's compilation: the
    server exits 0 at once and logs no error and no traceback (the pool's interrupted loading
    is part of the shutdown, not a failure)."""
    server, _ = _first_start(tmp_path)
    server.start()
    client = server.client()
    try:
        _wait_until_compiling(server, client)
        assert server.process is not None
        os.killpg(server.process.pid, signal.SIGINT)
        assert server.process.wait(timeout=60) == 0
    finally:
        client.close()
        server.stop()
    log = server.log_text()
    assert "ERROR" not in log and "Traceback" not in log, log
    assert "BrokenProcessPool" not in log, log
    assert "the job pool stopped before the solver was loaded" in log
    assert "Application shutdown complete" in log


def test_the_command_line_says_when_it_compiles(tmp_path: Path) -> None:
    """``trajopt solve`` on an empty kernel cache says on stderr why it waits; on the filled
    cache it does not."""
    env = service_free_env()
    env.update(TRAJOPT_DATA_DIR=str(tmp_path / "data"), NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    notice = "compiling the solver's kernels"
    runs = []
    for _ in range(2):
        done = run_cli("solve", SCENARIO, "--quiet", env=env, cwd=tmp_path, timeout=300)
        assert done.returncode == 0, done.stderr
        runs.append(done.stderr)
    assert notice in runs[0], runs[0]
    assert notice not in runs[1], runs[1]
    # the warm-up command says which it did: the cache is filled, so it loads
    done = subprocess.run(
        [sys.executable, "-m", "worker.solver.warmup"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    assert done.stdout.startswith("solver kernels loaded from numba's cache in "), done.stdout
