"""The HTTP layer: status codes, headers, the error shape, SSE framing and the OpenAPI document.

Runs the real application on a SQLite file. The dispatcher only records job ids (no solve), and
tests play the worker's part through the repository where a job must progress or finish.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.main import create_app
from app.settings import Settings
from app.storage import repository
from app.storage.session import Database, get_database
from worker.limits import TimeLimits

SCENARIO = "rlv-min-heat-load"


class RecordingDispatcher:
    """Accepts jobs without running them."""

    kind = "local"

    def __init__(self) -> None:
        self.submitted: list[tuple[str, TimeLimits]] = []
        self.priorities: list[int] = []

    def start(self) -> None:
        pass

    def submit(self, job_id: str, limits: TimeLimits, priority: int = 0) -> None:
        self.submitted.append((job_id, limits))
        self.priorities.append(priority)

    def carried(self, job_ids: object) -> set[str] | None:
        return None

    def ping(self) -> str | None:
        return None

    def queue_depth(self) -> int | None:
        return len(self.submitted)

    def shutdown(self) -> None:
        pass


@pytest.fixture
def settings(tmp_path: Path) -> Settings:
    return Settings(data_dir=tmp_path, database_url="", broker_url="", event_poll_interval_s=0.01)


@pytest.fixture
def dispatcher() -> RecordingDispatcher:
    return RecordingDispatcher()


@pytest.fixture
def client(settings: Settings, dispatcher: RecordingDispatcher) -> Iterator[TestClient]:
    with TestClient(create_app(settings, dispatcher)) as test_client:
        yield test_client


@pytest.fixture
def database(client: TestClient, settings: Settings) -> Database:
    return get_database(settings.effective_database_url)


def small_job() -> dict[str, Any]:
    return {"scenario": SCENARIO, "method": {"nodes": 20, "max_iterations": 3}}


def submit(client: TestClient, body: dict[str, Any] | None = None, key: str | None = None) -> str:
    headers = {"Idempotency-Key": key} if key else {}
    response = client.post("/v1/jobs", json=body or small_job(), headers=headers)
    assert response.status_code == 202, response.text
    job_id: str = response.json()["id"]
    return job_id


def run_as_worker(database: Database, job_id: str, iterations: int, finish: str | None) -> None:
    with database.session() as s:
        attempt = repository.claim_attempt(s, job_id, 3).attempt
    history: list[dict[str, Any]] = []
    for k in range(1, iterations + 1):
        history.append({"iteration": k, "cost": 1.0 / k, "max_state_change": 0.5 / k})
        with database.session() as s:
            repository.record_iteration(s, job_id, attempt, list(history), {"iteration": k})
    if finish is not None:
        with database.session() as s:
            repository.transition(
                s,
                job_id,
                to=finish,
                allowed_from=["running"],
                values={"result": {"status": finish, "history": history}, "history": history},
            )


def assert_error(response: Any, status: int, code: str) -> dict[str, Any]:
    assert response.status_code == status, response.text
    body = response.json()
    assert set(body) >= {"error"}
    assert {"code", "message", "field"} <= set(body["error"])
    assert body["error"]["code"] == code
    error: dict[str, Any] = body["error"]
    return error


def test_submit_returns_202_location_and_queues(
    client: TestClient, dispatcher: RecordingDispatcher
) -> None:
    response = client.post("/v1/jobs", json=small_job())
    assert response.status_code == 202
    job = response.json()
    assert response.headers["location"] == f"/v1/jobs/{job['id']}"
    assert (job["status"], job["attempts"], job["progress"]) == ("queued", 0, None)
    assert dispatcher.submitted[0][0] == job["id"]
    assert client.get(response.headers["location"]).json()["id"] == job["id"]


def test_idempotency_key(client: TestClient, dispatcher: RecordingDispatcher) -> None:
    first = submit(client, key="order-1")
    reordered = dict(reversed(list(small_job().items())))
    again = client.post("/v1/jobs", json=reordered, headers={"Idempotency-Key": "order-1"})
    assert again.status_code == 202
    assert again.json()["id"] == first
    assert again.headers["idempotent-replayed"] == "true"
    assert len(dispatcher.submitted) == 1
    other = {**small_job(), "method": {"nodes": 30}}
    error = assert_error(
        client.post("/v1/jobs", json=other, headers={"Idempotency-Key": "order-1"}),
        422,
        "idempotency_key_reused",
    )
    assert error["field"] == "Idempotency-Key"
    assert submit(client, key="order-2") != first


def test_invalid_problem_lists_every_bad_field(client: TestClient) -> None:
    body = {
        "scenario": SCENARIO,
        "overrides": {"method": {"nodes": 1}, "vehicle": {"mass_kg": -5}, "bogus": 1},
    }
    error = assert_error(client.post("/v1/jobs", json=body), 422, "invalid_problem")
    fields = {issue["field"] for issue in error["issues"]}
    assert {"method.nodes", "vehicle.mass_kg", "bogus"} <= fields
    assert all({"field", "message", "code"} == set(i) for i in error["issues"])
    assert client.get("/v1/jobs").json()["total"] == 0
    as_json = {"Content-Type": "application/json"}
    assert_error(client.post("/v1/jobs", content=b"[1]", headers=as_json), 422, "invalid_request")
    assert_error(
        client.post("/v1/jobs", content=b"{not json", headers=as_json), 400, "malformed_body"
    )
    assert_error(client.post("/v1/jobs", content=b"[1]"), 415, "unsupported_media_type")


@pytest.mark.parametrize(
    ("method", "path"),
    [
        ("GET", "/v1/jobs/{id}"),
        ("GET", "/v1/jobs/{id}/result"),
        ("GET", "/v1/jobs/{id}/history"),
        ("GET", "/v1/jobs/{id}/events"),
        ("DELETE", "/v1/jobs/{id}"),
    ],
)
def test_unknown_job_is_404(client: TestClient, method: str, path: str) -> None:
    response = client.request(method, path.format(id="00000000-0000-0000-0000-000000000000"))
    assert_error(response, 404, "job_not_found")


def test_error_shape_for_unknown_routes_methods_and_parameters(client: TestClient) -> None:
    assert_error(client.get("/v1/nothing"), 404, "not_found")
    assert_error(client.put("/v1/jobs"), 405, "method_not_allowed")
    error = assert_error(client.get("/v1/jobs?limit=0"), 422, "invalid_request")
    assert error["field"] == "limit"
    assert_error(client.get("/v1/jobs?status=bogus"), 422, "invalid_request")


def test_result_and_history_through_a_jobs_life(client: TestClient, database: Database) -> None:
    job_id = submit(client)
    assert_error(client.get(f"/v1/jobs/{job_id}/result"), 409, "job_not_finished")
    run_as_worker(database, job_id, iterations=2, finish=None)
    job = client.get(f"/v1/jobs/{job_id}").json()
    assert (job["status"], job["attempts"], job["progress"]["iteration"]) == ("running", 1, 2)
    assert job["elapsed_s"] >= 0
    history = client.get(f"/v1/jobs/{job_id}/history").json()
    assert [r["iteration"] for r in history["iterations"]] == [1, 2]
    assert_error(client.get(f"/v1/jobs/{job_id}/result"), 409, "job_not_finished")
    with database.session() as s:
        repository.transition(
            s, job_id, to="succeeded", allowed_from=["running"], values={"result": {"ok": 1}}
        )
    assert client.get(f"/v1/jobs/{job_id}/result").json() == {"ok": 1}
    assert client.get(f"/v1/jobs/{job_id}").json()["finished_at"] is not None


def test_cancel(client: TestClient, database: Database) -> None:
    queued, running, done = submit(client), submit(client), submit(client)
    response = client.delete(f"/v1/jobs/{queued}")
    assert (response.status_code, response.json()["status"]) == (200, "cancelled")
    assert client.delete(f"/v1/jobs/{queued}").status_code == 200
    assert_error(client.get(f"/v1/jobs/{queued}/result"), 409, "result_unavailable")
    run_as_worker(database, running, iterations=1, finish=None)
    response = client.delete(f"/v1/jobs/{running}")
    assert response.status_code == 202
    assert (response.json()["status"], response.json()["cancel_requested"]) == ("running", True)
    run_as_worker(database, done, iterations=1, finish="succeeded")
    assert_error(client.delete(f"/v1/jobs/{done}"), 409, "job_finished")


def test_listing_filters_and_paginates(client: TestClient) -> None:
    ids = [submit(client) for _ in range(3)]
    client.delete(f"/v1/jobs/{ids[0]}")
    page = client.get("/v1/jobs?limit=2").json()
    assert (page["total"], len(page["items"]), page["next_offset"]) == (3, 2, 2)
    assert [j["id"] for j in page["items"]] == [ids[2], ids[1]]
    last = client.get("/v1/jobs?limit=2&offset=2").json()
    assert ([j["id"] for j in last["items"]], last["next_offset"]) == ([ids[0]], None)
    cancelled = client.get("/v1/jobs?status=cancelled").json()
    assert [j["id"] for j in cancelled["items"]] == [ids[0]]
    both = client.get("/v1/jobs?status=cancelled&status=queued").json()
    assert both["total"] == 3


def parse_sse(text: str) -> list[dict[str, str]]:
    events = []
    for block in text.replace("\r\n", "\n").split("\n\n"):
        fields: dict[str, str] = {}
        for line in block.split("\n"):
            if line and not line.startswith(":") and ":" in line:
                name, _, value = line.partition(":")
                fields[name] = value.removeprefix(" ")
        if "event" in fields:
            events.append(fields)
    return events


def test_events_of_a_finished_job_and_resume(client: TestClient, database: Database) -> None:
    job_id = submit(client)
    run_as_worker(database, job_id, iterations=3, finish="succeeded")
    response = client.get(f"/v1/jobs/{job_id}/events")
    assert response.headers["content-type"].startswith("text/event-stream")
    events = parse_sse(response.text)
    assert [e["event"] for e in events] == ["iteration"] * 3 + ["end"]
    assert [e["id"] for e in events[:3]] == ["1", "2", "3"]
    assert '"status": "succeeded"' in events[-1]["data"]
    again = client.get(f"/v1/jobs/{job_id}/events", headers={"Last-Event-ID": "2"})
    resumed = parse_sse(again.text)
    assert [e["event"] for e in resumed] == ["iteration", "end"]
    assert '"iteration": 3' in resumed[0]["data"]


def test_events_arrive_live_while_the_job_runs(client: TestClient, database: Database) -> None:
    job_id = submit(client)

    def worker() -> None:
        time.sleep(0.2)
        run_as_worker(database, job_id, iterations=4, finish="failed")

    thread = threading.Thread(target=worker)
    thread.start()
    with client.stream("GET", f"/v1/jobs/{job_id}/events") as response:
        text = "".join(response.iter_text())
    thread.join()
    events = parse_sse(text)
    assert [e["event"] for e in events] == ["iteration"] * 4 + ["end"]
    assert '"status": "failed"' in events[-1]["data"]


def test_health_readiness_and_metrics(client: TestClient) -> None:
    assert client.get("/healthz").json()["status"] == "ok"
    ready = client.get("/readyz").json()
    assert ready == {"status": "ready", "checks": {"database": "ok", "local": "ok"}}
    submit(client)
    text = client.get("/metrics").text
    assert 'trajopt_jobs{status="queued"} 1.0' in text
    assert "trajopt_queue_depth 1.0" in text
    assert 'trajopt_job_solve_seconds_bucket{le="+Inf"} 0.0' in text


def test_scenarios_and_validation(client: TestClient) -> None:
    listed = client.get("/v1/scenarios").json()
    assert {"name", "title", "source"} <= set(listed[0])
    assert SCENARIO in {s["name"] for s in listed}
    one = client.get(f"/v1/scenarios/{SCENARIO}").json()
    assert "problem" in one
    assert isinstance(one["corrections"], list)
    assert_error(client.get("/v1/scenarios/nope"), 404, "scenario_not_found")
    valid = client.post("/v1/problems/validate", json=one["problem"])
    assert valid.status_code == 200
    assert valid.json()["valid"] is True
    bad = {**one["problem"], "schema_version": "9", "extra": 1}
    error = assert_error(client.post("/v1/problems/validate", json=bad), 422, "invalid_problem")
    assert {"schema_version", "extra"} <= {i["field"] for i in error["issues"]}


def test_methods(client: TestClient) -> None:
    methods = client.get("/v1/methods").json()
    assert methods
    assert all({"name", "features", "default_options"} <= set(m) for m in methods)


def test_openapi_documents_bodies_with_examples(client: TestClient) -> None:
    spec = client.get("/openapi.json").json()
    assert "ProblemDocument" in spec["components"]["schemas"]
    assert "ScenarioJobRequest" in spec["components"]["schemas"]
    bodies = 0
    for path, operations in spec["paths"].items():
        for verb, operation in operations.items():
            body = operation.get("requestBody")
            if body is None:
                continue
            bodies += 1
            content = body["content"]["application/json"]
            assert content.get("examples"), f"{verb.upper()} {path} has no body examples"
            if path == "/v1/batches":  # a base problem and how the children differ
                assert content["schema"] == {"$ref": "#/components/schemas/BatchRequest"}
            else:  # a problem document or a scenario request
                assert "oneOf" in content["schema"]
    assert bodies == 3
    assert "BatchRequest" in spec["components"]["schemas"]
    assert "HTTPValidationError" not in spec["components"]["schemas"]
    listing_422 = spec["paths"]["/v1/jobs"]["get"]["responses"]["422"]
    assert listing_422["content"]["application/json"]["schema"]["$ref"].endswith("/ErrorResponse")
    responses = spec["paths"]["/v1/jobs/{job_id}"]["get"]["responses"]
    assert responses["404"]["content"]["application/json"]["schema"]["$ref"].endswith(
        "/ErrorResponse"
    )
