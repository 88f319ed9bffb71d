"""A document without a method over real HTTP (``trajopt serve`` on its embedded defaults): auto
picks the method, the job says which, the result lists the attempts and the history is tagged
with them; a document no method accepts is a 422 naming each method's reasons."""

from __future__ import annotations

import copy
from typing import Any

import pytest

from tests.integration.harness import ServiceClient
from worker.solver.scenarios import get_scenario

pytestmark = pytest.mark.slow


def _without_method(scenario: str) -> dict[str, Any]:
    document: dict[str, Any] = copy.deepcopy(get_scenario(scenario).problem)
    del document["method"]
    return document


def test_a_document_without_a_method_is_solved_by_auto(embedded_client: ServiceClient) -> None:
    job = embedded_client.submit(_without_method("rlv-min-heat-load"))
    assert job["method"] == "auto"
    finished = embedded_client.wait_finished(job["id"])
    assert finished["status"] == "succeeded", finished
    assert finished["progress"]["method"] == "energy-scp"  # the web page's "auto → energy-scp"
    result = embedded_client.http.get(f"/v1/jobs/{job['id']}/result").json()
    assert result["method"] == "energy-scp"
    (attempt,) = result["attempts"]
    assert (attempt["method"], attempt["status"], attempt["kept"]) == (
        "energy-scp",
        "succeeded",
        True,
    )
    assert result["provenance"]["selection"]["chosen"] == "energy-scp"
    problem = embedded_client.http.get(f"/v1/jobs/{job['id']}/problem").json()
    assert problem["method"]["name"] == "auto"
    history = embedded_client.http.get(f"/v1/jobs/{job['id']}/history").json()["iterations"]
    assert len(history) == attempt["iterations"]
    assert {(r["extra"]["auto_attempt"], r["extra"]["method"]) for r in history} == {
        (1, "energy-scp")
    }


def test_a_document_no_method_accepts_is_refused_with_each_methods_reasons(
    embedded_client: ServiceClient,
) -> None:
    document = _without_method("rlv-min-time-hp")
    document["final_time"] = {"kind": "fixed", "value_s": 1500.0}
    document["objective"] = "min_control_effort"  # only hp-scp takes it, on a free final time
    for path in ("/v1/problems/validate", "/v1/jobs"):
        response = embedded_client.http.post(path, json=document)
        assert response.status_code == 422, response.text
        error = response.json()["error"]
        lead, *reasons = error["issues"]
        assert (error["field"], lead["code"]) == ("method", "no_method_accepts")
        assert {i["message"].split(" ", 1)[0].rstrip(":") for i in reasons} == {
            "energy-scp",
            "foh-ptr",
            "hp-scp",
            "cheb-scvx",
            "lgl-sqp",
        }
        assert {"field": "final_time", "code": "unsupported_by_method"}.items() <= next(
            i for i in reasons if i["message"].startswith("hp-scp ")
        ).items()


def test_the_methods_route_serves_auto_and_the_capability_matrix(
    embedded_client: ServiceClient,
) -> None:
    methods = embedded_client.http.get("/v1/methods").json()
    assert [m["name"] for m in methods] == [
        "auto",
        "energy-scp",
        "foh-ptr",
        "hp-scp",
        "cheb-scvx",
        "lgl-sqp",
    ]
    matrix = {m["name"]: m["capabilities"] for m in methods}
    assert matrix["energy-scp"]["final_time"] == {"free": True, "fixed": False}
    assert matrix["auto"]["final_time"] == {"free": True, "fixed": True}
    assert [m["preference"] for m in methods] == [None, 1, 2, 4, 3, 5]
