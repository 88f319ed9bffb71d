"""``trajopt serve`` on its embedded defaults: SQLite in the data folder, jobs in a local pool.

No Redis, no PostgreSQL, no separate worker: the commands a fresh machine runs first.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.integration.harness import (
    SCENARIO,
    ApiServer,
    ServiceClient,
    cancel_during_verification,
    embedded_env,
    long_job,
    verification_job,
)

pytestmark = pytest.mark.slow


def _running(job: dict[str, Any]) -> bool:
    return job["status"] == "running" and (job["progress"] or {}).get("iteration", 0) >= 1


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("embedded-data")


@pytest.fixture(scope="module")
def server(data_dir: Path) -> Iterator[ApiServer]:
    yield from ApiServer(embedded_env(data_dir), data_dir / "serve.log").serving()


@pytest.fixture
def client(server: ApiServer) -> Iterator[ServiceClient]:
    yield from server.serving_client()


@pytest.fixture(scope="module")
def scenario() -> str:
    from worker.solver.scenarios import get_scenario

    return get_scenario(SCENARIO).name


def test_serve_prints_the_docs_address_and_uses_sqlite(
    server: ApiServer, client: ServiceClient, data_dir: Path
) -> None:
    assert f"http://127.0.0.1:{server.port}/docs" in server.log_text()
    assert (data_dir / "trajopt.sqlite3").is_file()
    ready = client.http.get("/readyz").json()
    assert ready["checks"] == {"database": "ok", "local": "ok"}
    assert client.http.get("/docs").status_code == 200


def test_scenario_job_runs_without_a_broker(client: ServiceClient, scenario: str) -> None:
    job = client.submit({"scenario": scenario})
    assert job["status"] == "queued"
    events = list(client.events(job["id"]))
    assert [e["event"] for e in events][-1] == "end"
    iterations = [e["data"]["iteration"] for e in events if e["event"] == "iteration"]
    assert iterations == list(range(1, len(iterations) + 1))
    phases = [e["data"]["phase"] for e in events if e["event"] == "phase"]
    # the verification takes tens of milliseconds: the stream may see its phase or not
    assert "optimizing" in phases and set(phases) <= {"compiling", "optimizing", "verifying"}
    assert events[-1]["data"]["status"] == "succeeded"
    result = client.http.get(f"/v1/jobs/{job['id']}/result").json()
    assert result["status"] == "succeeded"
    assert len(result["history"]) == len(iterations)


def test_failure_and_cancellation(client: ServiceClient, scenario: str) -> None:
    failing = client.submit({"scenario": scenario, "method": {"max_iterations": 2}})
    done = client.wait_finished(failing["id"])
    assert (done["status"], done["error"]["code"]) == ("failed", "max_iterations")

    running = client.submit(long_job(scenario))
    client.wait_for(running["id"], _running, 60, "first iteration")
    queued = client.submit({"scenario": scenario})
    response = client.http.delete(f"/v1/jobs/{queued['id']}")
    assert (response.status_code, response.json()["status"]) == (200, "cancelled")
    assert client.http.delete(f"/v1/jobs/{running['id']}").status_code == 202
    done = client.wait_finished(running["id"], timeout=30)
    assert done["status"] == "cancelled"
    assert client.http.get(f"/v1/jobs/{running['id']}/history").json()["iterations"]


def test_a_finished_job_says_finished(client: ServiceClient, scenario: str) -> None:
    """A terminal job's progress phase is ``finished`` (its last iteration's figures kept), in
    the job view and in the stream's end event alike."""
    job = client.submit({"scenario": scenario, "method": {"nodes": 41, "max_iterations": 2}})
    events = list(client.events(job["id"]))
    assert events[-1]["event"] == "end"
    assert events[-1]["data"]["progress"]["phase"] == "finished"
    done = client.job(job["id"])
    assert done["status"] == "failed"
    assert (done["progress"]["phase"], done["progress"]["iteration"]) == ("finished", 2)
    listed = client.http.get("/v1/jobs", params={"limit": 5}).json()["items"]
    assert next(j for j in listed if j["id"] == job["id"])["progress"]["phase"] == "finished"


def test_a_cancel_during_the_optimization_says_where_it_stopped(
    client: ServiceClient, scenario: str
) -> None:
    """A running job cancelled between SCP iterations: the failure says it stopped during the
    optimization and before which iteration (the history's next), and no verification ran. A
    job cancelled while it waited in the queue says finished too."""
    running = client.submit(long_job(scenario))
    client.wait_for(
        running["id"], lambda j: _running(j) and j["progress"]["iteration"] >= 2, 60, "iteration 2"
    )
    queued = client.submit({"scenario": scenario})
    assert client.http.delete(f"/v1/jobs/{queued['id']}").status_code == 200
    assert client.job(queued["id"])["progress"] == {
        "phase": "finished",
        "method": None,
        "iteration": None,
        "cost": None,
        "max_state_change": None,
        "conic_status": None,
        "elapsed_s": None,
    }
    assert client.http.delete(f"/v1/jobs/{running['id']}").status_code == 202
    done = client.wait_finished(running["id"], timeout=60)
    result = client.http.get(f"/v1/jobs/{running['id']}/result").json()
    kept = len(result["history"])
    expected = (
        f"stopped during the optimization, before iteration {kept + 1}; the trajectory is the "
        "last iterate and was not verified"
    )
    assert (done["status"], done["error"]["code"]) == ("cancelled", "cancelled")
    assert done["error"]["message"] == result["failure"]["message"] == expected
    assert result["verification"] is None and result["trajectory"] is not None
    assert done["progress"]["phase"] == "finished"


def test_cancel_during_the_verification_stops_it(client: ServiceClient, scenario: str) -> None:
    cancel_during_verification(client, scenario)


def test_the_time_limit_covers_the_verification(client: ServiceClient, scenario: str) -> None:
    """Three quick iterations, then a verification of many CPU seconds: a 2 s limit (CPU time,
    which the worker holds the verification to) ends it."""
    body = verification_job(scenario)
    body["method"]["time_limit_s"] = 2.0
    job = client.submit(body)
    done = client.wait_finished(job["id"], timeout=120)
    assert (done["status"], done["error"]["code"]) == ("timed_out", "time_limit")
    result = client.http.get(f"/v1/jobs/{job['id']}/result").json()
    assert result["verification"] is None and len(result["history"]) == 3
    # the limit plus one stop-poll interval (the uncut verification alone takes several times
    # the limit); CPU time, so a busy machine does not move it
    assert result["timing"]["cpu_s"] < 2.0 + 0.5
    assert "stopped at the job's CPU time limit of 2 s" in done["error"]["message"]


def test_restart_keeps_jobs_and_resumes_unfinished_ones(
    server: ApiServer, client: ServiceClient, scenario: str
) -> None:
    listing_before = client.http.get("/v1/jobs?limit=100").json()
    interrupted = client.submit(long_job(scenario))
    client.wait_for(interrupted["id"], _running, 60, "first iteration")
    waiting = client.submit({"scenario": scenario, "method": {"max_iterations": 2}})
    server.stop()
    server.start_and_wait()

    resumed = client.wait_for(
        interrupted["id"], lambda j: j["attempts"] == 2 and _running(j), 60, "second attempt"
    )
    assert resumed["status"] == "running"
    client.http.delete(f"/v1/jobs/{interrupted['id']}")
    assert client.wait_finished(interrupted["id"], timeout=30)["status"] == "cancelled"
    assert client.wait_finished(waiting["id"])["status"] == "failed"
    listing_after = client.http.get("/v1/jobs?limit=100").json()
    assert listing_after["total"] == listing_before["total"] + 2
    old = {j["id"]: j for j in listing_after["items"]}
    for job in listing_before["items"]:
        assert {k: old[job["id"]][k] for k in ("status", "finished_at", "attempts")} == {
            k: job[k] for k in ("status", "finished_at", "attempts")
        }
