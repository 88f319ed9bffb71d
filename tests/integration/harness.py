"""Helpers to run the service for real: free ports, subprocesses, HTTP and SSE clients.

Shared by the integration tests (Redis + PostgreSQL + Celery worker) and the end-to-end tests
(embedded mode). Processes run from the repository root with the current interpreter.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from datetime import datetime
from pathlib import Path
from typing import Any, TextIO

import httpx
import psycopg
import pytest
import redis

from bench.load_faults import NEVER_CONVERGE

REPO_ROOT = Path(__file__).resolve().parents[2]
SCENARIO = "rlv-min-heat-load"
"""The built-in scenario the service tests submit."""
TERMINAL = frozenset({"succeeded", "failed", "cancelled", "timed_out"})


def long_job(scenario: str) -> dict[str, Any]:
    """A job that runs for many seconds, iterating all the while (for cancel tests)."""
    method = {
        "nodes": 200,
        "max_iterations": 500,
        "time_limit_s": 120,
        "stop_tolerance": NEVER_CONVERGE,
    }
    return {"scenario": scenario, "method": method}


SERVICE_ENV_NAMES = ("DATABASE_URL", "REDIS_URL", "CELERY_BROKER_URL")
"""Service variables without the ``TRAJOPT_`` prefix."""


def service_free_env(**settings: str) -> dict[str, str]:
    """This process's environment without any service setting, plus ``settings``: a child
    process started with it sees only what the test sets."""
    env = {
        k: v
        for k, v in os.environ.items()
        if not k.startswith("TRAJOPT_") and k not in SERVICE_ENV_NAMES
    }
    env.update(settings)
    return env


def embedded_env(data_dir: Path | str, **settings: str) -> dict[str, str]:
    """The environment of an embedded server (SQLite in ``data_dir``, a one-process pool)."""
    return service_free_env(TRAJOPT_DATA_DIR=str(data_dir), TRAJOPT_LOCAL_WORKERS="1", **settings)


US76_FEASIBLE = {
    "planet": {"atmosphere": {"model": "us76"}},
    "path_constraints": {"heat_rate": {"max_W_m2": 1.2e6}},
}
"""Overrides of the built-in scenario to the US76 atmosphere, with its heat-rate limit raised
above the first heating peak of full lift-up flight there (1 108 kW/m^2), which no bank
profile lowers: with the scenario's 1 000 kW/m^2 the pre-checks refuse it at once."""


def verification_job(scenario: str) -> dict[str, Any]:
    """A job whose verification takes many seconds after three quick iterations: 1000 nodes and
    the US76 atmosphere, a table with no compiled form, so the propagation runs its right-hand
    side in Python (about 5 s; the compiled models verify the same job in about 1 s)."""
    return {
        "scenario": scenario,
        "overrides": US76_FEASIBLE,
        "method": {"nodes": 1000, "max_iterations": 3},
    }


def verifying(job: dict[str, Any]) -> bool:
    """Whether the job's attempt is verifying its answer."""
    return job["status"] == "running" and (job["progress"] or {}).get("phase") == "verifying"


def cancel_during_verification(client: ServiceClient, scenario: str) -> None:
    """Cancel a job while it verifies: 202, then ``cancelled`` with the verification cut short
    and the history kept (a verification that ran on would leave its report)."""
    job = client.submit(verification_job(scenario))
    client.wait_for(job["id"], verifying, 180, "the verification phase")
    response = client.http.delete(f"/v1/jobs/{job['id']}")
    assert response.status_code == 202, response.text
    done = client.wait_finished(job["id"], timeout=60)
    assert (done["status"], done["error"]["code"]) == ("cancelled", "cancelled")
    result = client.http.get(f"/v1/jobs/{job['id']}/result").json()
    assert result["status"] == "cancelled"
    assert result["verification"] is None
    assert "during the verification" in result["failure"]["message"]
    assert len(result["history"]) == 3


def assert_fair_share(first: ServiceClient, second: ServiceClient, scenario: str) -> None:
    """With one worker process busy on ``first``'s backlog of four jobs, ``second``'s single job
    starts before ``first``'s third: clients get fair shares, not first come, first served
    (which would start it after all four)."""
    backlog = [first.submit({"scenario": scenario})["id"] for _ in range(4)]
    first.wait_for(backlog[0], lambda j: j["status"] == "running", 120, "the first job running")
    small = {"scenario": scenario, "method": {"nodes": 41, "max_iterations": 8}}
    late = second.submit(small)["id"]
    done = second.wait_finished(late, timeout=180)
    finished = [first.wait_finished(job_id, timeout=180) for job_id in backlog]
    started = [datetime.fromisoformat(j["started_at"]) for j in finished]
    late_start = datetime.fromisoformat(done["started_at"])
    assert started[0] < late_start < started[2], (done, finished)  # no pre-emption either


def free_port() -> int:
    """A TCP port on the loopback interface that nothing listens on right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


SKIP_MISSING_SERVICES = "TRAJOPT_TEST_SKIP_MISSING_SERVICES"
"""Set to 1 to skip, rather than fail, the tests whose service (Redis, PostgreSQL, Chromium) is
missing: a developer's explicit choice, never the default."""


def require(service: str, reason: str | None) -> None:
    """Fail the test when ``service`` is unreachable (``reason`` set): a missing service is a
    broken test run, not a pass. Skipped only when the developer sets
    ``TRAJOPT_TEST_SKIP_MISSING_SERVICES=1``."""
    if reason is None:
        return
    message = f"{service} is not reachable: {reason}"
    if os.environ.get(SKIP_MISSING_SERVICES) == "1":
        pytest.skip(message)
    pytest.fail(
        f"{message} (bash .ci/run starts it; {SKIP_MISSING_SERVICES}=1 skips)", pytrace=False
    )


def admin_postgres_url() -> str:
    """A URL of the loopback PostgreSQL that can create schemas (trust auth): the first of
    ``TEST_POSTGRES_URL`` or the users ``postgres`` and ``root`` that answers; the test fails
    naming each refusal when none does."""
    given = os.environ.get("TEST_POSTGRES_URL")
    candidates = (
        [given]
        if given
        else [
            "postgresql://postgres@127.0.0.1:5432/test",
            "postgresql://root@127.0.0.1:5432/test",
        ]
    )
    errors = []
    for url in candidates:
        try:
            with psycopg.connect(url, connect_timeout=3) as conn:
                conn.execute("SELECT 1")
            return url
        except psycopg.Error as exc:
            errors.append(f"{url}: {exc}".strip())
    require("PostgreSQL", "; ".join(errors))
    raise AssertionError("unreachable")


def forget_queue(redis_url: str, queue: str) -> None:
    """Delete a Celery queue's Redis lists (one per priority) and kombu's binding keys."""
    from worker.celery_app import priority_lists

    client = redis.Redis.from_url(redis_url)
    try:
        bindings = (f"_kombu.binding.{queue}", f"_kombu.binding_permanent.{queue}")
        client.delete(*priority_lists(queue), *bindings)
        if client.keys("*") == [b"_kombu.binding_deadlines"]:  # only kombu's bookkeeping left
            client.delete("_kombu.binding_deadlines")
    finally:
        client.close()


class ServiceProcess:
    """A child process of the service with its output in a log file."""

    def __init__(self, args: list[str], env: dict[str, str], log_path: Path) -> None:
        self.args = args
        self.env = env
        self.log_path = log_path
        self.process: subprocess.Popen[bytes] | None = None
        self._log: TextIO | None = None

    def start(self) -> None:
        """Start the process (a new session, so it can be stopped with its children)."""
        self._log = self.log_path.open("a", encoding="utf-8")
        self.process = subprocess.Popen(
            [sys.executable, *self.args],
            cwd=REPO_ROOT,
            env=self.env,
            stdout=self._log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )

    def log_text(self) -> str:
        """Everything the process printed so far."""
        return self.log_path.read_text(encoding="utf-8", errors="replace")

    def alive(self) -> bool:
        """Whether the process still runs."""
        return self.process is not None and self.process.poll() is None

    def stop(self, timeout: float = 20.0) -> None:
        """SIGTERM the process group, then SIGKILL it if it does not exit in time."""
        if self.process is not None and self.process.poll() is None:
            try:
                os.killpg(self.process.pid, signal.SIGTERM)
                self.process.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                os.killpg(self.process.pid, signal.SIGKILL)
                self.process.wait(timeout=timeout)
            except ProcessLookupError:
                pass
        if self._log is not None:
            self._log.close()
            self._log = None

    def wait_for_output(self, text: str, timeout: float) -> None:
        """Block until ``text`` appears in the log; fail with the log if it does not."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if text in self.log_text():
                return
            if not self.alive():
                break
            time.sleep(0.1)
        pytest.fail(f"{' '.join(self.args)} did not print {text!r}:\n{self.log_text()[-4000:]}")


class ApiServer(ServiceProcess):
    """``trajopt serve`` on a free loopback port."""

    def __init__(self, env: dict[str, str], log_path: Path, api_key: str | None = None) -> None:
        self.port = free_port()
        self.base_url = f"http://127.0.0.1:{self.port}"
        self.api_key = api_key
        args = ["-m", "app.cli", "serve", "--host", "127.0.0.1", "--port", str(self.port)]
        super().__init__(args, env, log_path)

    def start_and_wait(self, timeout: float = 60.0) -> None:
        """Start and wait until ``/readyz`` answers 200."""
        self.start()
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if not self.alive():
                break
            try:
                if httpx.get(f"{self.base_url}/readyz", timeout=2).status_code == 200:
                    return
            except httpx.HTTPError:
                pass
            time.sleep(0.2)
        self.stop()
        pytest.fail(f"the API did not become ready:\n{self.log_text()[-4000:]}")

    def client(self) -> ServiceClient:
        """An HTTP client of this server (sending this server's API key, if any)."""
        return ServiceClient(self.base_url, self.api_key)

    def serving(self) -> Iterator[ApiServer]:
        """Fixture body: start, wait until ready, yield this server, stop it afterwards."""
        self.start_and_wait()
        try:
            yield self
        finally:
            self.stop()

    def serving_client(self) -> Iterator[ServiceClient]:
        """Fixture body: yield a client of this server and close it afterwards."""
        client = self.client()
        try:
            yield client
        finally:
            client.close()


def run_cli(
    *args: str,
    env: dict[str, str],
    cwd: Path = REPO_ROOT,
    timeout: float = 120.0,
    check: bool = False,
) -> subprocess.CompletedProcess[str]:
    """Run ``python -m app.cli ARGS`` (the ``trajopt`` command) to its end, output captured."""
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        check=check,
        timeout=timeout,
    )


def create_api_key(env: dict[str, str], client: str) -> str:
    """Run ``trajopt keys create --client`` with ``env`` and return the printed key."""
    return run_cli("keys", "create", "--client", client, env=env, check=True).stdout.strip()


def run_keys_command(env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    """Run ``trajopt keys ARGS`` with ``env``."""
    return run_cli("keys", *args, env=env)


class ServiceClient:
    """Thin HTTP client of the job API used by the tests."""

    def __init__(self, base_url: str, api_key: str | None = None) -> None:
        self.base_url = base_url
        self.api_key = api_key
        headers = {"X-API-Key": api_key} if api_key else {}
        self.http = httpx.Client(base_url=base_url, timeout=30.0, headers=headers)

    def submit(self, body: dict[str, Any], key: str | None = None) -> dict[str, Any]:
        """POST a job; asserts 202 and the Location header."""
        headers = {"Idempotency-Key": key} if key else {}
        response = self.http.post("/v1/jobs", json=body, headers=headers)
        assert response.status_code == 202, response.text
        job: dict[str, Any] = response.json()
        assert response.headers["location"] == f"/v1/jobs/{job['id']}"
        return job

    def job(self, job_id: str) -> dict[str, Any]:
        """GET the job; asserts 200."""
        response = self.http.get(f"/v1/jobs/{job_id}")
        assert response.status_code == 200, response.text
        job: dict[str, Any] = response.json()
        return job

    def wait_for(
        self,
        job_id: str,
        predicate: Callable[[dict[str, Any]], bool],
        timeout: float = 120.0,
        what: str = "condition",
    ) -> dict[str, Any]:
        """Poll the job until ``predicate`` holds."""
        deadline = time.monotonic() + timeout
        job = self.job(job_id)
        while not predicate(job):
            if time.monotonic() > deadline:
                pytest.fail(f"job {job_id}: {what} not reached in {timeout} s; last: {job}")
            time.sleep(0.05)
            job = self.job(job_id)
        return job

    def wait_finished(self, job_id: str, timeout: float = 180.0) -> dict[str, Any]:
        """Poll until the job is in a terminal state."""
        return self.wait_for(job_id, lambda j: j["status"] in TERMINAL, timeout, "finish")

    def events(self, job_id: str, timeout: float = 180.0) -> Iterator[dict[str, Any]]:
        """The job's server-sent events as ``{"event", "id", "data"}`` with data decoded."""
        with self.http.stream("GET", f"/v1/jobs/{job_id}/events", timeout=timeout) as response:
            assert response.status_code == 200
            assert response.headers["content-type"].startswith("text/event-stream")
            fields: dict[str, str] = {}
            for line in response.iter_lines():
                if line == "":
                    if "event" in fields:
                        yield {
                            "event": fields["event"],
                            "id": fields.get("id"),
                            "data": json.loads(fields.get("data", "null")),
                        }
                    fields = {}
                elif not line.startswith(":"):
                    name, _, value = line.partition(":")
                    fields[name] = value.removeprefix(" ")

    def close(self) -> None:
        """Close the connection pool."""
        self.http.close()
