"""The OpenAPI document tells the truth, and the docs pages need nothing but this server.

- ``/docs`` and ``/redoc`` reference only this server's files, and each of those answers 200.
- Every documented example is valid against the schema it documents.
- Every documented error example is an answer the service really gives (same status, code,
  field and wording), produced here by a request that provokes it.
- A body that is not decodable JSON is a 400 ``malformed_body`` naming the position.
"""

from __future__ import annotations

import contextlib
import json
import re
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.auth import create_key
from app.docs_ui import CONTENT_SECURITY_POLICY
from app.main import create_app
from app.render_pool import RenderPool
from app.routes.examples import ERROR_EXAMPLES, JOB_ID, RESULT_EXAMPLES
from app.schemas import RLV_MIN_HEAT_LOAD
from app.schemas.result import ResultDocument
from app.settings import Settings
from app.storage.session import get_database
from tests.openapi_schemas import OpenApiSchemas
from tests.unit.test_service_api import RecordingDispatcher, run_as_worker

SCENARIO = "rlv-min-heat-load"
UUID = re.compile(r"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}")
JSON = {"Content-Type": "application/json"}


def _settings(tmp: Path, **overrides: Any) -> Settings:
    return Settings(**{"data_dir": tmp, "database_url": "", "broker_url": "", **overrides})


@pytest.fixture
def client(tmp_path: Path) -> Iterator[TestClient]:
    with TestClient(create_app(_settings(tmp_path), RecordingDispatcher())) as test_client:
        yield test_client


@pytest.fixture
def spec(client: TestClient) -> dict[str, Any]:
    document: dict[str, Any] = client.get("/openapi.json").json()
    return document


# --- the docs pages ----------------------------------------------------------------------


@pytest.mark.parametrize("page", ["/docs", "/redoc"])
def test_docs_pages_load_only_files_of_this_server(client: TestClient, page: str) -> None:
    response = client.get(page)
    assert response.status_code == 200
    assert response.headers["content-security-policy"] == CONTENT_SECURITY_POLICY
    html = response.text
    assert not re.findall(r"(?:https?:)?//[\w.-]+", html.replace("http-equiv", "")), html
    assets = re.findall(r'(?:src|href)="([^"]+)"', html) + re.findall(r"url: '([^']+)'", html)
    assets += re.findall(r'spec-url="([^"]+)"', html)
    assert len(assets) >= 3, html
    for asset in assets:
        assert asset.startswith("/"), asset
        assert client.get(asset).status_code == 200, asset
    assert "/openapi.json" in assets


def test_the_policy_allows_no_other_origin() -> None:
    for directive in CONTENT_SECURITY_POLICY.split("; "):
        sources = directive.split()[1:]
        assert set(sources) <= {"'self'", "'unsafe-inline'", "'unsafe-eval'", "data:", "blob:"}


# --- examples against their schemas ---------------------------------------------------------


def _documented_examples(spec: dict[str, Any]) -> Iterator[tuple[str, dict[str, Any], Any]]:
    for path, operations in spec["paths"].items():
        for method, operation in operations.items():
            for status, response in operation.get("responses", {}).items():
                content = response.get("content", {}).get("application/json", {})
                for name, example in content.get("examples", {}).items():
                    where = f"{method.upper()} {path} {status} {name}"
                    yield where, content["schema"], example["value"]


def test_every_documented_response_example_fits_its_schema(spec: dict[str, Any]) -> None:
    schemas = OpenApiSchemas(spec)
    checked = 0
    for where, schema, value in _documented_examples(spec):
        assert schemas.errors(value, schema) == [], where
        checked += 1
    assert checked > 40


def test_result_and_history_are_documented_with_their_models(spec: dict[str, Any]) -> None:
    schemas = OpenApiSchemas(spec)
    result = schemas.response_schema("/v1/jobs/{job_id}/result", "get", 200)
    assert result == {"$ref": "#/components/schemas/ResultDocument"}
    history = spec["components"]["schemas"]["HistoryView"]["properties"]["iterations"]
    assert history["items"] == {"$ref": "#/components/schemas/HistoryRecord"}
    not_an_iteration = {"job_id": JOB_ID, "status": "running", "iterations": [{"cost": 1.0}]}
    assert schemas.errors(not_an_iteration, schemas.component("HistoryView"))
    assert schemas.errors({"status": "succeeded"}, result)  # no method, no timing


def test_result_examples_are_solver_output(spec: dict[str, Any]) -> None:
    documented = spec["paths"]["/v1/jobs/{job_id}/result"]["get"]["responses"]["200"]
    assert set(documented["content"]["application/json"]["examples"]) == set(RESULT_EXAMPLES)
    names = set()
    for example in RESULT_EXAMPLES.values():
        document = example["value"]
        ResultDocument.model_validate(document)
        trajectory = document["trajectory"]
        assert all(
            len(column) == trajectory["nodes"]
            for name, column in trajectory.items()
            if name not in ("units", "nodes")
        )
        assert document["provenance"]["method_options"]["nodes"] == trajectory["nodes"]
        assert document["history"][-1]["iteration"] == document["timing"]["iterations"]
        names.add(document["provenance"]["problem_name"])
    assert len(names) == 2


# --- error examples are real answers -------------------------------------------------------


def _masked(text: str) -> str:
    """``text`` with job ids, quoted keys and numbers replaced, for comparing wordings."""
    text = UUID.sub("<id>", text)
    return re.sub(r"\d+(?:\.\d+)?", "<n>", text)


def _same_error(documented: dict[str, Any], answered: dict[str, Any]) -> None:
    want, got = documented["error"], answered["error"]
    assert got["code"] == want["code"]
    assert got["field"] == want["field"]
    assert _masked(got["message"]) == _masked(want["message"]), (got, want)
    if "issues" in want:
        assert [(i["field"], i["code"]) for i in got["issues"]] == [
            (i["field"], i["code"]) for i in want["issues"]
        ]
        assert [_masked(i["message"]) for i in got["issues"]] == [
            _masked(i["message"]) for i in want["issues"]
        ]
    assert set(answered) == set(documented)


class NotReady(RecordingDispatcher):
    """A pool that is down."""

    def ping(self) -> str | None:
        return "local job pool not running"


class Unreachable(RecordingDispatcher):
    """A queue that refuses every job."""

    def submit(self, job_id: str, limits: Any) -> None:
        raise ConnectionError("connection refused")


def _apps(tmp: Path) -> dict[str, TestClient]:
    """Applications set up so that each documented error can be provoked."""
    keyed = _settings(
        tmp / "keys",
        auth_mode="api-keys",
        api_key_secret="docs-test-only-0123456789abcdef012345",
        rate_read_per_window=1,
        rate_submit_per_window=1,
    )
    return {
        "default": TestClient(create_app(_settings(tmp / "default"), RecordingDispatcher())),
        "keys": TestClient(create_app(keyed, RecordingDispatcher())),
        "capped": TestClient(
            create_app(_settings(tmp / "capped", max_active_jobs=1), RecordingDispatcher())
        ),
        "streams": TestClient(
            create_app(_settings(tmp / "streams", max_streams_per_client=10), RecordingDispatcher())
        ),
        "down": TestClient(create_app(_settings(tmp / "down"), NotReady())),
        "no_database": TestClient(
            create_app(
                _settings(
                    tmp / "no-database",
                    database_url="postgresql+psycopg://nobody@127.0.0.1:1/none",
                    auto_migrate=False,
                ),
                RecordingDispatcher(),
            )
        ),
        "unreachable": TestClient(create_app(_settings(tmp / "unreachable"), Unreachable())),
        "renders": TestClient(create_app(_settings(tmp / "renders"), RecordingDispatcher())),
    }


class HeldRenders(Executor):
    """Render processes that never finish a render until told to (``release``), or that are
    broken (``broken``): a render queue that stays full, a render process that dies."""

    def __init__(self) -> None:
        self.held: list[Future[Any]] = []
        self.broken = False

    def submit(self, fn: Any, /, *args: Any, **kwargs: Any) -> Future[Any]:
        if self.broken:
            raise BrokenProcessPool("a render process died")
        future: Future[Any] = Future()
        self.held.append(future)
        return future

    def release(self) -> None:
        for future in self.held:
            future.set_result(b"\x89PNG")


def _invalid_problem() -> dict[str, Any]:
    return {
        **RLV_MIN_HEAT_LOAD,
        "vehicle": {**RLV_MIN_HEAT_LOAD["vehicle"], "mass_kg": -1},
        "method": {"name": "energy-scp", "nodes": 1},
    }


def _provokers(apps: dict[str, TestClient], tmp: Path) -> dict[str, Callable[[], Any]]:
    """For each documented error example, the request that gets that error for real."""
    default, keys = apps["default"], apps["keys"]
    database = get_database(_settings(tmp / "keys").effective_database_url)
    settings = keys.app.state.service.settings  # type: ignore[attr-defined]
    reader, submitter = (create_key(database, settings, c)[1] for c in ("reader", "submitter"))
    scenario = {"scenario": SCENARIO}

    def queued() -> str:
        job_id: str = default.post("/v1/jobs", json=scenario).json()["id"]
        return job_id

    def cancelled() -> str:
        job_id = queued()
        assert default.delete(f"/v1/jobs/{job_id}").status_code == 200
        return job_id

    def succeeded() -> str:
        job_id = queued()
        run_as_worker(
            get_database(_settings(tmp / "default").effective_database_url), job_id, 1, "succeeded"
        )
        return job_id

    def reused_key() -> Any:
        headers = {"Idempotency-Key": "nightly-42"}
        assert default.post("/v1/jobs", json=scenario, headers=headers).status_code == 202
        return default.post("/v1/jobs", json={**scenario, "method": {"nodes": 30}}, headers=headers)

    def read_twice() -> Any:
        keys.get("/v1/jobs", headers={"X-API-Key": reader})
        return keys.get("/v1/jobs", headers={"X-API-Key": reader})

    def submit_twice() -> Any:
        keys.post("/v1/jobs", json=scenario, headers={"X-API-Key": submitter})
        return keys.post("/v1/jobs", json=scenario, headers={"X-API-Key": submitter})

    renders = apps["renders"]
    held = HeldRenders()
    service = renders.app.state.service  # type: ignore[attr-defined]
    service.renders = RenderPool(1, 1, make_executor=lambda _: held)

    def rendered_job() -> str:
        job_id: str = renders.post("/v1/jobs", json=scenario).json()["id"]
        run_as_worker(service.database, job_id, 1, "succeeded")
        return job_id

    def second_render() -> Any:
        """A plot being rendered (held), then another of the same client: its queue of one
        is full."""
        job_id = rendered_job()
        with ThreadPoolExecutor(1) as thread:
            first = thread.submit(renders.get, f"/v1/jobs/{job_id}/plots/convergence.png")
            while not held.held:
                time.sleep(0.01)
            refused = renders.get(f"/v1/jobs/{job_id}/plots/convergence.svg")
            held.release()
            assert first.result().status_code == 200
        return refused

    def broken_renders() -> Any:
        held.broken = True
        return renders.get(f"/v1/jobs/{rendered_job()}/plots/convergence.png")

    def eleven_streams() -> Any:
        """Ten streams of a queued job held open (they only ping), then one more."""
        streams = apps["streams"]
        job_id = streams.post("/v1/jobs", json=scenario).json()["id"]
        with contextlib.ExitStack() as held:
            for _ in range(10):
                opened = held.enter_context(streams.stream("GET", f"/v1/jobs/{job_id}/events"))
                assert opened.status_code == 200
            return streams.get(f"/v1/jobs/{job_id}/events")

    def two_active() -> Any:
        assert apps["capped"].post("/v1/jobs", json=scenario).status_code == 202
        return apps["capped"].post("/v1/jobs", json=scenario)

    limit = default.app.state.service.settings.max_body_bytes  # type: ignore[attr-defined]
    return {
        "malformed_body": lambda: default.post("/v1/jobs", content=b'{"scenario": ', headers=JSON),
        "missing_api_key": lambda: keys.get("/v1/jobs"),
        "invalid_api_key": lambda: keys.get("/v1/jobs", headers={"X-API-Key": "tk_not-a-key"}),
        "job_not_found": lambda: default.get(f"/v1/jobs/{JOB_ID}"),
        "scenario_not_found": lambda: default.get("/v1/scenarios/rlv-min-heatload"),
        "job_not_finished": lambda: default.get(f"/v1/jobs/{queued()}/result"),
        "result_unavailable": lambda: default.get(f"/v1/jobs/{cancelled()}/result"),
        "job_finished": lambda: default.delete(f"/v1/jobs/{succeeded()}"),
        # a result with a history and no trajectory: its only plot is the convergence
        "batch_not_found": lambda: default.get(f"/v1/batches/{JOB_ID}"),
        "invalid_batch": lambda: default.post(
            "/v1/batches",
            json={
                "base": {"scenario": "rlv-max-terminal-velocity-active-nfz"},
                "grid": {"parameters": [{"path": "/no_fly_zones/0/radius_deg", "values": [-1.0]}]},
            },
        ),
        "no_trajectory": lambda: default.get(f"/v1/jobs/{succeeded()}/trajectory.csv"),
        "plot_not_found": lambda: default.get(f"/v1/jobs/{succeeded()}/plots/ground-track.png"),
        "plot_format_not_found": lambda: default.get(f"/v1/jobs/{succeeded()}/plots/states.jpg"),
        "body_too_large": lambda: default.post(
            "/v1/jobs", content=b" " * (limit + 1), headers=JSON
        ),
        "unsupported_media_type": lambda: default.post(
            "/v1/jobs", content=json.dumps(scenario), headers={"Content-Type": "text/plain"}
        ),
        "invalid_problem": lambda: default.post("/v1/jobs", json=_invalid_problem()),
        "invalid_request": lambda: default.post("/v1/jobs", json={**scenario, "nodes": 20}),
        "invalid_parameter": lambda: default.get("/v1/jobs?limit=0"),
        "over_server_cap": lambda: default.post(
            "/v1/jobs", json={**scenario, "method": {"nodes": 1500}}
        ),
        "invalid_idempotency_key": lambda: default.post(
            "/v1/jobs", json=scenario, headers={"Idempotency-Key": "x" * 256}
        ),
        "idempotency_key_reused": reused_key,
        "rate_limited": read_twice,
        "submit_rate_limited": submit_twice,
        "too_many_active_jobs": two_active,
        "too_many_streams": eleven_streams,
        "too_many_renders": second_render,
        "render_unavailable": broken_renders,
        "queue_unavailable": lambda: apps["unreachable"].post("/v1/jobs", json=scenario),
        "not_ready": lambda: apps["down"].get("/readyz"),
        "database_unavailable": lambda: apps["no_database"].get("/v1/jobs"),
    }


def test_every_error_example_is_what_the_service_answers(tmp_path: Path) -> None:
    apps = _apps(tmp_path)
    for app in apps.values():
        app.__enter__()
    try:
        provokers = _provokers(apps, tmp_path)
        assert set(provokers) == set(ERROR_EXAMPLES)
        for name, example in ERROR_EXAMPLES.items():
            response = provokers[name]()
            assert response.status_code == example["x-status"], (name, response.text)
            _same_error(example["value"], response.json())
    finally:
        for app in apps.values():
            app.__exit__(None, None, None)


def test_every_error_response_has_examples_of_its_status(spec: dict[str, Any]) -> None:
    for path, operations in spec["paths"].items():
        for method, operation in operations.items():
            for status, response in operation["responses"].items():
                content = response.get("content", {}).get("application/json", {})
                if not status.startswith(("4", "5")):
                    continue
                examples = content.get("examples")
                assert examples, f"{method.upper()} {path} {status}"
                for name in examples:
                    assert ERROR_EXAMPLES[name]["x-status"] == int(status), (path, name)
    assert "400" not in spec["paths"]["/v1/jobs"]["get"]["responses"]  # no body, no 400
    assert "415" in spec["paths"]["/v1/problems/validate"]["post"]["responses"]


# --- bodies that are not JSON ----------------------------------------------------------------


@pytest.mark.parametrize("path", ["/v1/jobs", "/v1/problems/validate"])
@pytest.mark.parametrize(
    ("body", "where"),
    [
        (b'{"scenario": ', "Expecting value at line 1, column 14 (character 13)"),
        (
            b'{\n  "scenario": "rlv",,\n}',
            "Expecting property name enclosed in double quotes at line 2, column 21 (character 22)",
        ),
        (b'{"scenario": "rlv-\xff"}', "it is not UTF-8 text (invalid start byte at byte 18)"),
        (b"\xff\xfe{}", "Expecting value at line 1, column 1 (character 0)"),  # UTF-16 BOM
        (b"", "Expecting value at line 1, column 1 (character 0)"),
    ],
)
def test_undecodable_bodies_are_400_naming_the_position(
    client: TestClient, path: str, body: bytes, where: str
) -> None:
    response = client.post(path, content=body, headers=JSON)
    assert response.status_code == 400, response.text
    error = response.json()["error"]
    assert error["code"] == "malformed_body"
    assert error["field"] is None
    assert error["message"] == f"the body is not valid JSON: {where}"
    assert client.get("/v1/jobs").json()["total"] == 0


@pytest.mark.parametrize("path", ["/v1/jobs", "/v1/problems/validate"])
def test_a_decodable_body_that_is_no_object_is_still_422(client: TestClient, path: str) -> None:
    response = client.post(path, content=b"[1, 2]", headers=JSON)
    assert (response.status_code, response.json()["error"]["code"]) == (422, "invalid_request")
