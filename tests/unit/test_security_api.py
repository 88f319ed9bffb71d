"""API keys, per-client isolation, request limits, CORS, error bodies and logs, over HTTP.

The real application runs on a SQLite file in api-keys mode; the dispatcher only records job
ids, and tests play the worker's part through the repository where a job must progress.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app import jobs_service
from app.auth import create_key, hash_key
from app.main import create_app
from app.settings import Settings
from app.storage import repository
from app.storage.session import Database, get_database
from tests.unit.test_service_api import RecordingDispatcher, assert_error, run_as_worker, small_job

SECRET = "0123456789abcdef0123456789abcdef-test-only"


class FailingDispatcher(RecordingDispatcher):
    """A queue that is down."""

    def submit(self, job_id: str, limits: Any, priority: int = 0) -> None:
        raise ConnectionError("Error 111 connecting to 127.0.0.1:1. Connection refused.")


def _settings(tmp_path: Path, **overrides: Any) -> Settings:
    values: dict[str, Any] = {
        "data_dir": tmp_path,
        "database_url": "",
        "broker_url": "",
        "event_poll_interval_s": 0.01,
        "auth_mode": "api-keys",
        "api_key_secret": SECRET,
    }
    values.update(overrides)
    return Settings(**values)


class Clients:
    """One application with two clients' keys: ``a`` and ``b`` (headers) and the test client."""

    def __init__(self, http: TestClient, settings: Settings, dispatcher: RecordingDispatcher):
        self.http = http
        self.settings = settings
        self.dispatcher = dispatcher
        self.database: Database = get_database(settings.effective_database_url)
        self.a_id, key_a = create_key(self.database, settings, "alpha")
        self.b_id, key_b = create_key(self.database, settings, "bravo")
        self.key_a, self.key_b = key_a, key_b
        self.a = {"X-API-Key": key_a}
        self.b = {"X-API-Key": key_b}

    def submit(self, headers: dict[str, str], body: dict[str, Any] | None = None) -> str:
        response = self.http.post("/v1/jobs", json=body or small_job(), headers=headers)
        assert response.status_code == 202, response.text
        job_id: str = response.json()["id"]
        return job_id


@pytest.fixture
def make_clients(tmp_path: Path) -> Iterator[Any]:
    opened: list[TestClient] = []

    def make(dispatcher: RecordingDispatcher | None = None, **overrides: Any) -> Clients:
        settings = _settings(tmp_path, **overrides)
        dispatcher = dispatcher or RecordingDispatcher()
        http = TestClient(create_app(settings, dispatcher))
        http.__enter__()
        opened.append(http)
        return Clients(http, settings, dispatcher)

    yield make
    for http in opened:
        http.__exit__(None, None, None)


def test_missing_unknown_and_revoked_keys_get_401(make_clients: Any) -> None:
    c = make_clients()
    for headers in ({}, {"X-API-Key": "tj_not-a-key"}, {"X-API-Key": "x" * 5000}):
        for method, path in (("GET", "/v1/jobs"), ("POST", "/v1/jobs"), ("GET", "/v1/methods")):
            response = c.http.request(method, path, headers=headers, json=small_job())
            code = "missing_api_key" if not headers else "invalid_api_key"
            assert_error(response, 401, code)
            assert response.headers["www-authenticate"] == "ApiKey"
    job_id = c.submit(c.a)
    assert c.http.get(f"/v1/jobs/{job_id}", headers=c.a).status_code == 200
    with c.database.session() as s:
        assert repository.revoke_api_key(s, c.a_id.id)
    assert_error(c.http.get(f"/v1/jobs/{job_id}", headers=c.a), 401, "invalid_api_key")
    assert c.http.get("/v1/jobs", headers=c.b).status_code == 200  # other keys unaffected
    assert c.http.get("/healthz").status_code == 200  # operational routes need no key


def test_only_the_hash_of_a_key_is_stored(make_clients: Any) -> None:
    c = make_clients()
    with c.database.reader() as s:
        rows = repository.list_api_keys(s)
    assert {r.client for r in rows} == {"alpha", "bravo"}
    stored = " ".join(f"{r.key_hash} {r.prefix}" for r in rows)
    assert c.key_a not in stored and c.key_b not in stored
    assert {r.key_hash for r in rows} == {hash_key(c.key_a, SECRET), hash_key(c.key_b, SECRET)}
    assert hash_key(c.key_a, SECRET) != hash_key(c.key_a, SECRET + "x")  # keyed by the secret


def test_client_b_cannot_see_or_touch_client_a_jobs(make_clients: Any) -> None:
    c = make_clients()
    running = c.submit(c.a)
    finished = c.submit(c.a)
    run_as_worker(c.database, running, iterations=2, finish=None)
    run_as_worker(c.database, finished, iterations=2, finish="succeeded")
    for job_id in (running, finished):
        for suffix in ("", "/result", "/history", "/events"):
            response = c.http.get(f"/v1/jobs/{job_id}{suffix}", headers=c.b)
            assert_error(response, 404, "job_not_found")
        assert_error(c.http.delete(f"/v1/jobs/{job_id}", headers=c.b), 404, "job_not_found")
    assert c.http.get("/v1/jobs", headers=c.b).json()["total"] == 0
    mine = c.submit(c.b)
    listed = c.http.get("/v1/jobs", headers=c.b).json()
    assert [j["id"] for j in listed["items"]] == [mine]
    assert listed["items"][0]["owner"] == "bravo"
    # A still sees its own jobs, untouched by B's cancel attempts.
    assert c.http.get(f"/v1/jobs/{running}", headers=c.a).json()["cancel_requested"] is False
    assert c.http.get("/v1/jobs", headers=c.a).json()["total"] == 2
    assert c.http.get(f"/v1/jobs/{finished}/result", headers=c.a).status_code == 200


def test_the_same_idempotency_key_is_private_to_each_client(make_clients: Any) -> None:
    c = make_clients()
    headers_a = {**c.a, "Idempotency-Key": "k1"}
    headers_b = {**c.b, "Idempotency-Key": "k1"}
    first = c.http.post("/v1/jobs", json=small_job(), headers=headers_a).json()["id"]
    second = c.http.post("/v1/jobs", json=small_job(), headers=headers_b).json()["id"]
    assert first != second


def test_body_size_limit_counts_bytes_not_the_header(make_clients: Any) -> None:
    c = make_clients(max_body_bytes=4096)
    padding = {"scenario": "rlv-min-heat-load", "overrides": {"description": "x" * 5000}}
    assert_error(c.http.post("/v1/jobs", json=padding, headers=c.a), 413, "body_too_large")

    def chunks() -> Iterator[bytes]:  # chunked transfer: no Content-Length at all
        yield b'{"scenario": "rlv-min-heat-load", "overrides": {"description": "'
        for _ in range(10):
            yield b"y" * 1000
        yield b'"}}'

    response = c.http.post(
        "/v1/jobs", content=chunks(), headers={**c.a, "Content-Type": "application/json"}
    )
    assert_error(response, 413, "body_too_large")
    assert c.http.get("/v1/jobs", headers=c.a).json()["total"] == 0
    assert c.submit(c.a)  # a small body still passes through the limit intact


def test_submission_and_read_rate_limits_per_client(make_clients: Any) -> None:
    c = make_clients(rate_submit_per_window=2, rate_read_per_window=3, rate_window_s=3600)
    a2 = {"X-API-Key": create_key(c.database, c.settings, "alpha")[1]}
    c.submit(c.a)
    c.submit(a2)  # the client's two keys share its budget: no key gets a budget of its own
    for headers in (c.a, a2):
        response = c.http.post("/v1/jobs", json=small_job(), headers=headers)
        error = assert_error(response, 429, "rate_limited")
        assert error["message"] == "too many submit requests: at most 2 per 3600 s"
        assert 3599 <= int(response.headers["retry-after"]) <= 3600  # when the oldest expires
    c.submit(c.b)  # another client has its own budget
    for headers in (c.a, a2, c.a):
        assert c.http.get("/v1/jobs", headers=headers).status_code == 200
    response = c.http.get("/v1/jobs", headers=a2)
    assert_error(response, 429, "rate_limited")
    assert int(response.headers["retry-after"]) >= 1
    assert c.http.get("/v1/jobs", headers=c.b).status_code == 200


def test_a_key_may_use_only_its_share_of_the_client_limit(make_clients: Any) -> None:
    c = make_clients(rate_submit_per_window=4, rate_key_share=0.5, rate_window_s=3600)
    a2, a3 = ({"X-API-Key": create_key(c.database, c.settings, "alpha")[1]} for _ in range(2))
    for headers in (c.a, c.a, a2, a2):
        c.submit(headers)
    error = assert_error(
        c.http.post("/v1/jobs", json=small_job(), headers=c.a), 429, "rate_limited"
    )
    assert error["message"] == "too many submit requests with this API key: at most 2 per 3600 s"
    error = assert_error(c.http.post("/v1/jobs", json=small_job(), headers=a3), 429, "rate_limited")
    assert error["message"] == "too many submit requests: at most 4 per 3600 s"  # the client's


def test_refused_submissions_use_the_rejected_quota_not_the_submit_quota(
    make_clients: Any,
) -> None:
    c = make_clients(rate_submit_per_window=2, rate_rejected_per_window=3, rate_window_s=3600)
    invalid = {**small_job(), "nodes": 20}
    for _ in range(2):
        assert_error(c.http.post("/v1/jobs", json=invalid, headers=c.a), 422, "invalid_request")
    replayed = {**c.a, "Idempotency-Key": "nightly-1"}
    first = c.http.post("/v1/jobs", json=small_job(), headers=replayed)
    assert first.status_code == 202, first.text
    c.submit(c.a)  # the two invalid bodies used none of the submit quota
    assert_error(c.http.post("/v1/jobs", json=small_job(), headers=c.a), 429, "rate_limited")
    again = c.http.post("/v1/jobs", json=small_job(), headers=replayed)  # a replay costs a read
    assert (again.status_code, again.json()["id"]) == (202, first.json()["id"])

    for _ in range(3):
        assert_error(c.http.post("/v1/jobs", json=invalid, headers=c.b), 422, "invalid_request")
    for body in (invalid, small_job()):  # refused before validation until the window moves
        response = c.http.post("/v1/jobs", json=body, headers=c.b)
        error = assert_error(response, 429, "rate_limited")
        assert error["message"] == "too many rejected submissions: at most 3 per 3600 s"
        assert int(response.headers["retry-after"]) >= 3599
    assert c.http.get("/v1/jobs", headers=c.b).json()["total"] == 0


def test_cap_on_queued_and_running_jobs_per_client(make_clients: Any) -> None:
    c = make_clients(max_active_jobs=2)
    first = c.submit(c.a)
    c.submit(c.a)
    response = c.http.post("/v1/jobs", json=small_job(), headers=c.a)
    error = assert_error(response, 429, "too_many_active_jobs")
    assert "TRAJOPT_MAX_ACTIVE_JOBS" in error["message"]
    assert response.headers["retry-after"]
    c.submit(c.b)  # the cap is per client
    run_as_worker(c.database, first, iterations=1, finish="succeeded")
    c.submit(c.a)  # a finished job frees a slot


@pytest.mark.parametrize(
    ("method", "field", "setting"),
    [
        ({"nodes": 60}, "method.nodes", "TRAJOPT_MAX_NODES"),
        ({"max_iterations": 11}, "method.max_iterations", "TRAJOPT_MAX_ITERATIONS"),
        ({"time_limit_s": 31}, "method.time_limit_s", "TRAJOPT_MAX_TIME_LIMIT_S"),
    ],
)
def test_server_caps_on_method_options_name_the_cap(
    make_clients: Any, method: dict[str, Any], field: str, setting: str
) -> None:
    c = make_clients(max_nodes=50, max_iterations=10, max_time_limit_s=30, default_time_limit_s=30)
    base = {"nodes": 20, "max_iterations": 5, "time_limit_s": 5}
    body = {"scenario": "rlv-min-heat-load", "method": {**base, **method}}
    for path in ("/v1/jobs", "/v1/problems/validate"):
        error = assert_error(c.http.post(path, json=body, headers=c.a), 422, "over_server_cap")
        assert error["field"] == field
        assert setting in error["message"]
        assert error["issues"][0]["code"] == "server_cap"
    assert c.dispatcher.submitted == []


def test_server_caps_on_zones_and_waypoints(make_clients: Any) -> None:
    c = make_clients(max_no_fly_zones=1, max_waypoints=0)
    zones = [
        {"center_latitude_deg": 80.0, "center_longitude_deg": lon, "radius_km": 10.0}
        for lon in (100.0, 150.0)
    ]
    waypoints = [{"latitude_deg": -80.0, "longitude_deg": 0.0, "radius_km": 50.0, "order": 1}]
    body = {
        "scenario": "rlv-min-heat-load",
        "overrides": {"no_fly_zones": zones, "waypoints": waypoints},
    }
    error = assert_error(c.http.post("/v1/jobs", json=body, headers=c.a), 422, "over_server_cap")
    assert {i["field"] for i in error["issues"]} == {"no_fly_zones", "waypoints"}
    messages = " ".join(i["message"] for i in error["issues"])
    assert "TRAJOPT_MAX_NO_FLY_ZONES=1" in messages and "TRAJOPT_MAX_WAYPOINTS=0" in messages


def test_nan_infinity_and_unknown_fields_are_rejected(make_clients: Any) -> None:
    c = make_clients()
    for literal in ("NaN", "Infinity", "-Infinity"):  # what Python's json module emits
        text = '{"scenario": "rlv-min-heat-load", "overrides": {"vehicle": {"mass_kg": '
        response = c.http.post(
            "/v1/jobs",
            content=text + literal + "}}}",
            headers={**c.a, "Content-Type": "application/json"},
        )
        assert response.status_code == 422, response.text
    for body in (
        {"scenario": "rlv-min-heat-load", "surprise": 1},
        {"scenario": "rlv-min-heat-load", "overrides": {"vehicle": {"surprise": 1}}},
    ):
        assert c.http.post("/v1/jobs", json=body, headers=c.a).status_code == 422
    assert c.dispatcher.submitted == []


def test_queue_outage_gives_503_with_retry_after_and_stores_nothing(make_clients: Any) -> None:
    c = make_clients(dispatcher=FailingDispatcher())
    response = c.http.post("/v1/jobs", json=small_job(), headers=c.a)
    error = assert_error(response, 503, "queue_unavailable")
    assert "nothing was stored" in error["message"]
    assert int(response.headers["retry-after"]) >= 1
    assert c.http.get("/v1/jobs", headers=c.a).json()["total"] == 0


def test_cors_is_closed_by_default_and_opens_per_origin(make_clients: Any, tmp_path: Path) -> None:
    preflight = {
        "Origin": "https://tools.example.org",
        "Access-Control-Request-Method": "POST",
        "Access-Control-Request-Headers": "x-api-key",
    }
    closed = make_clients()
    response = closed.http.options("/v1/jobs", headers=preflight)
    assert "access-control-allow-origin" not in response.headers
    response = closed.http.get("/v1/jobs", headers={**closed.a, "Origin": preflight["Origin"]})
    assert "access-control-allow-origin" not in response.headers

    opened = make_clients(
        cors_origins="https://tools.example.org", data_dir=tmp_path / "cors"
    )  # another database file: keys are per application here
    response = opened.http.options("/v1/jobs", headers=preflight)
    assert response.headers["access-control-allow-origin"] == "https://tools.example.org"
    evil = opened.http.options("/v1/jobs", headers={**preflight, "Origin": "https://evil.test"})
    assert "access-control-allow-origin" not in evil.headers


def test_unexpected_errors_show_no_stack_trace(
    make_clients: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    def broken(*_: Any, **__: Any) -> Any:
        raise RuntimeError("secret internal detail /srv/app/jobs.py line 42")

    monkeypatch.setattr(jobs_service, "list_jobs", broken)
    c = make_clients()
    c.http = TestClient(c.http.app, raise_server_exceptions=False)
    response = c.http.get("/v1/jobs", headers=c.a)
    assert_error(response, 500, "internal_error")
    assert "secret" not in response.text and "Traceback" not in response.text
    assert "jobs.py" not in response.text


def test_logs_name_job_and_client_but_never_the_key(
    make_clients: Any, caplog: pytest.LogCaptureFixture
) -> None:
    c = make_clients()
    with caplog.at_level(logging.DEBUG):
        job_id = c.submit(c.a)
        c.http.get(f"/v1/jobs/{job_id}", headers=c.a)
        c.http.get(f"/v1/jobs/{job_id}", headers=c.b)
        with c.database.session() as s:
            repository.revoke_api_key(s, c.b_id.id)
        c.http.get("/v1/jobs", headers=c.b)
    text = "\n".join(r.getMessage() for r in caplog.records)
    assert f"job {job_id} accepted for client alpha" in text
    assert c.key_a not in text and c.key_b not in text
    assert c.key_a[:12] not in text  # not even a long prefix


def test_single_user_mode_needs_no_key(tmp_path: Path) -> None:
    settings = Settings(data_dir=tmp_path, database_url="", broker_url="")
    with TestClient(create_app(settings, RecordingDispatcher())) as http:
        job = http.post("/v1/jobs", json=small_job()).json()
        assert job["owner"] == "default"
        assert http.get(f"/v1/jobs/{job['id']}").status_code == 200
