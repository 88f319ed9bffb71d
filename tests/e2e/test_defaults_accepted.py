"""A server on its default settings accepts every built-in scenario and every method's defaults:
no server cap may sit below what the project itself ships (validate, submit and batches)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from app.schemas import METHOD_NAMES
from tests.integration.harness import ApiServer, ServiceClient, embedded_env
from worker.solver.scenarios import list_scenarios

pytestmark = pytest.mark.slow

SCENARIOS = [s.name for s in list_scenarios()]


def _method_defaults_document(method: str) -> dict[str, Any]:
    """A built-in scenario of ``method`` with the method given by its name alone (its defaults);
    the merge patch replaces the whole method object when ``name`` is given."""
    scenario = next(s for s in list_scenarios() if s.problem["method"]["name"] == method)
    return {"scenario": scenario.name, "overrides": {"method": {"name": method}}}


@pytest.fixture(scope="module")
def default_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ApiServer]:
    """An embedded server with no setting changed but its data folder and a one-process pool."""
    data = tmp_path_factory.mktemp("defaults")
    yield from ApiServer(embedded_env(data), data / "serve.log").serving()


@pytest.fixture
def http(default_server: ApiServer) -> Iterator[ServiceClient]:
    yield from default_server.serving_client()


def _cancel(http: ServiceClient, path: str) -> None:
    response = http.http.delete(path)
    assert response.status_code in (200, 202), response.text


@pytest.mark.parametrize("body", [{"scenario": name} for name in SCENARIOS], ids=SCENARIOS)
def test_every_scenario_validates_and_is_accepted(
    http: ServiceClient, body: dict[str, Any]
) -> None:
    validation = http.http.post("/v1/problems/validate", json=body)
    assert validation.status_code == 200, validation.text
    job = http.submit(body)  # asserts 202
    _cancel(http, f"/v1/jobs/{job['id']}")


@pytest.mark.parametrize("method", METHOD_NAMES)
def test_every_methods_defaults_validate_and_are_accepted(http: ServiceClient, method: str) -> None:
    body = _method_defaults_document(method)
    validation = http.http.post("/v1/problems/validate", json=body)
    assert validation.status_code == 200, validation.text
    job = http.submit(body)
    _cancel(http, f"/v1/jobs/{job['id']}")
    batch = http.http.post(
        "/v1/batches", json={"base": {"scenario": body["scenario"]}, "methods": [{"name": method}]}
    )
    assert batch.status_code in (201, 202), batch.text
    _cancel(http, f"/v1/batches/{batch.json()['id']}")


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_auto_with_its_defaults_is_accepted_on_every_scenario(
    http: ServiceClient, scenario: str
) -> None:
    """Auto's defaults (and the defaults of each method it would run) sit within the caps."""
    body = {"scenario": scenario, "overrides": {"method": {"name": "auto"}}}
    validation = http.http.post("/v1/problems/validate", json=body)
    assert validation.status_code == 200, validation.text
    assert validation.json()["problem"]["method"]["name"] == "auto"


def test_a_batch_of_methods_may_leave_a_child_to_auto(http: ServiceClient) -> None:
    batch = http.http.post(
        "/v1/batches",
        json={
            "base": {"scenario": "rlv-max-terminal-velocity"},
            "methods": [{"name": "auto"}, {"name": "foh-ptr"}],
        },
    )
    assert batch.status_code in (201, 202), batch.text
    _cancel(http, f"/v1/batches/{batch.json()['id']}")
