"""Batches on the real stack: PostgreSQL, Redis and two Celery worker processes. A grid of 20
children runs across both workers and its summary agrees with every child's own result; a
batch is its owner's only; a batch over the active-job cap waits; cancelling stops its
children."""

from __future__ import annotations

import csv
import io
import time
from collections.abc import Iterator
from typing import Any

import psycopg
import pytest

from tests.integration.conftest import celery_worker
from tests.integration.harness import (
    ApiServer,
    ServiceClient,
    ServiceProcess,
    create_api_key,
    long_job,
)

pytestmark = pytest.mark.slow

ZONE_SCENARIO = "rlv-max-terminal-velocity-active-nfz"
RADII = [1.0, 1.5, 2.0, 2.5, 3.0]
HEAT_LIMITS = [1.45e6, 1.5e6, 1.6e6, 1.8e6]


@pytest.fixture(scope="module")
def second_worker(
    stack_env: dict[str, str], worker: ServiceProcess, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[ServiceProcess]:
    """A second Celery worker process on the same queue."""
    yield from celery_worker(stack_env, tmp_path_factory.mktemp("logs") / "worker-2.log")


def _wait_batch(client: ServiceClient, batch_id: str, timeout: float = 240.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while True:
        batch: dict[str, Any] = client.http.get(f"/v1/batches/{batch_id}").json()
        if batch["status"] != "running":
            return batch
        assert time.monotonic() < deadline, batch
        time.sleep(0.5)


def test_a_grid_of_20_runs_on_both_workers_and_its_summary_is_each_childs_result(
    client: ServiceClient, worker: ServiceProcess, second_worker: ServiceProcess
) -> None:
    body = {
        "name": "zone radius x heat-rate limit",
        "base": {"scenario": ZONE_SCENARIO},
        "grid": {
            "parameters": [
                {"path": "/no_fly_zones/0/radius_deg", "values": RADII},
                {"path": "/path_constraints/heat_rate/max_W_m2", "values": HEAT_LIMITS},
            ]
        },
    }
    answer = client.http.post("/v1/batches", json=body)
    assert answer.status_code == 202, answer.text
    batch = answer.json()
    assert answer.headers["location"] == f"/v1/batches/{batch['id']}"
    assert batch["size"] == 20 and batch["counts"] == {"queued": 20}
    done = _wait_batch(client, batch["id"])
    assert done["status"] == "finished" and sum(done["counts"].values()) == 20
    answered = client.http.get(f"/v1/batches/{batch['id']}/summary")
    assert answered.status_code == 200, answered.text
    summary = answered.json()
    rows = summary["rows"]
    assert summary["parameters"] == [p["path"] for p in body["grid"]["parameters"]]
    expected = [(r, q) for r in RADII for q in HEAT_LIMITS]
    assert [tuple(row["parameters"].values()) for row in rows] == expected
    for row in rows:
        job = client.job(row["job_id"])
        assert job["status"] == row["status"]
        result = client.http.get(f"/v1/jobs/{row['job_id']}/result").json()
        problem_zone = result["verification"]["no_fly_zones"][0]
        radius = row["parameters"]["/no_fly_zones/0/radius_deg"]
        assert problem_zone["radius_deg"] == pytest.approx(radius, rel=1e-12)  # via radians
        limit = result["verification"]["path_maxima"]["heat_rate_W_m2"]["limit"]
        assert limit == row["parameters"]["/path_constraints/heat_rate/max_W_m2"]
        assert row["objective"] == result["objective"]["value"]
        final = result["verification"]["final_state"]
        assert row["final_velocity_m_s"] == final["velocity_m_s"]
        assert row["iterations"] == len(result["history"])
        assert row["feasible"] == result["verification"]["feasible"]
    succeeded = [row for row in rows if row["status"] == "succeeded"]
    assert len(succeeded) >= 15, [(r["parameters"], r["failure_code"]) for r in rows]
    # a larger zone on the path costs terminal speed (same heat limit, both succeeded)
    by_key = {tuple(r["parameters"].values()): r["objective"] for r in succeeded}
    for q in HEAT_LIMITS:
        if (1.0, q) in by_key and (3.0, q) in by_key:
            assert by_key[(3.0, q)] < by_key[(1.0, q)]
    table = list(
        csv.reader(io.StringIO(client.http.get(f"/v1/batches/{batch['id']}/summary.csv").text))
    )
    assert len(table) == 21 and table[0][2:4] == summary["parameters"]
    assert client.http.get(f"/v1/batches/{batch['id']}/plot.png").content[:4] == b"\x89PNG"
    ran = [
        {row["job_id"] for row in rows if f"job {row['job_id']}: attempt 1 started" in w.log_text()}
        for w in (worker, second_worker)
    ]
    assert all(ran) and ran[0].isdisjoint(ran[1]), [len(r) for r in ran]
    assert len(ran[0] | ran[1]) == 20


def test_batches_are_their_owners_and_count_towards_the_active_cap(
    api: ApiServer, stack_env: dict[str, str], client: ServiceClient
) -> None:
    other = ServiceClient(api.base_url, create_api_key(stack_env, "batch-other"))
    try:
        body = {
            "base": {"scenario": ZONE_SCENARIO, "method": {"max_iterations": 1}},
            "methods": [{"name": "foh-ptr"}],
        }
        batch = client.http.post("/v1/batches", json=body).json()
        for suffix in ("", "/summary", "/summary.csv", "/plot.png"):
            assert other.http.get(f"/v1/batches/{batch['id']}{suffix}").status_code == 404
        assert other.http.delete(f"/v1/batches/{batch['id']}").status_code == 404
        assert other.http.get("/v1/batches").json()["total"] == 0
        huge = {
            "base": {"scenario": ZONE_SCENARIO},
            "monte_carlo": {
                "samples": 101,
                "dispersions": [
                    {"path": "/vehicle/mass_kg", "distribution": "normal", "sigma": 10}
                ],
            },
        }
        refused = client.http.post("/v1/batches", json=huge)
        assert (
            refused.status_code == 422 and refused.json()["error"]["field"] == "monte_carlo.samples"
        )
    finally:
        other.close()


def test_cancelling_a_batch_stops_its_children(client: ServiceClient) -> None:
    slow = long_job(ZONE_SCENARIO)
    body = {
        "base": {"scenario": ZONE_SCENARIO, "method": slow["method"]},
        "grid": {
            "parameters": [{"path": "/no_fly_zones/0/radius_deg", "values": [1.0, 2.0, 3.0, 4.0]}]
        },
    }
    batch = client.http.post("/v1/batches", json=body).json()
    deadline = time.monotonic() + 120
    while client.http.get(f"/v1/batches/{batch['id']}").json()["counts"].get("running", 0) < 1:
        assert time.monotonic() < deadline, "no child of the batch started"
        time.sleep(0.2)
    cancelled = client.http.delete(f"/v1/batches/{batch['id']}").json()
    assert cancelled["cancel_requested"] is True
    done = _wait_batch(client, batch["id"], timeout=120)
    assert done["status"] == "cancelled" and done["counts"] == {"cancelled": 4}
    rows = client.http.get(f"/v1/batches/{batch['id']}/summary").json()["rows"]
    assert {row["failure_code"] for row in rows} == {"cancelled"}


def test_a_grid_child_starts_from_the_callers_own_job_as_a_single_job_does(
    api: ApiServer, stack_env: dict[str, str], client: ServiceClient, scenario: str
) -> None:
    """``initial_guess.from_job`` set by a grid parameter: the caller's own finished job is
    accepted and its trajectory copied into the child (as for a single job); another
    client's job is a 404 naming the child."""
    source = client.wait_finished(client.submit({"scenario": scenario})["id"])
    assert source["status"] == "succeeded"
    grid = {
        "parameters": [
            {"path": "/initial_guess", "values": [{"from_job": source["id"]}]},
            {"path": "/method/max_iterations", "values": [20, 30]},
        ]
    }
    body = {"base": {"scenario": scenario}, "grid": grid}
    answer = client.http.post("/v1/batches", json=body)
    assert answer.status_code == 202, answer.text
    done = _wait_batch(client, answer.json()["id"])
    assert done["counts"] == {"succeeded": 2}, done
    rows = client.http.get(f"/v1/batches/{answer.json()['id']}/summary").json()["rows"]
    with psycopg.connect(stack_env["DATABASE_URL"]) as conn:
        for row in rows:
            guess = conn.execute(
                "SELECT problem->'initial_guess' FROM jobs WHERE id = %s", (row["job_id"],)
            ).fetchone()[0]
            assert guess["from_job"] == source["id"]
            assert len(guess["trajectory"]["time_s"]) > 2  # copied from the source job

    other = ServiceClient(api.base_url, create_api_key(stack_env, "grid-guess-other"))
    try:
        refused = other.http.post("/v1/batches", json=body)
        assert refused.status_code == 404, refused.text
        assert refused.json()["error"]["field"] == "children[0].initial_guess.from_job"
        assert other.http.get("/v1/batches").json()["total"] == 0
    finally:
        other.close()
