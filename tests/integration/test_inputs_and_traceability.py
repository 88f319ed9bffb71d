"""What a job says of its input, through the whole service (PostgreSQL, Redis, a Celery worker,
uvicorn): node counts a method cannot use refused at validation, plausibility warnings in the
validation answer, the job view and the result (and named first when the solve fails), and the
problem as solved served by ``GET /v1/jobs/{id}/problem`` (route, Python client, ``trajopt
problem``), fingerprinted in the result's provenance with the scenario, overrides and source
job it came from."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from typing import Any

import pytest

from app.client import NotFoundError, TrajoptClient
from tests.integration.harness import REPO_ROOT, ApiServer, ServiceClient, create_api_key

pytestmark = pytest.mark.slow

FOH = "rlv-max-terminal-velocity"
"""foh-ptr's scenario: a start it cannot make fails at once."""
SMALL = {"nodes": 20, "max_iterations": 3}
"""A solve of a fraction of a second (it ends failed, by its iteration budget)."""


def _sha256(document: Any) -> str:
    """The canonical fingerprint, written out here rather than imported from the service."""
    text = json.dumps(document, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _finished_result(client: ServiceClient, job_id: str) -> dict[str, Any]:
    client.wait_finished(job_id, timeout=120)
    response = client.http.get(f"/v1/jobs/{job_id}/result")
    assert response.status_code == 200, response.text
    result: dict[str, Any] = response.json()
    return result


def test_too_few_nodes_are_refused_and_implausible_values_warned(client: ServiceClient) -> None:
    few = client.http.post("/v1/problems/validate", json={"scenario": FOH, "method": {"nodes": 3}})
    assert few.status_code == 422, few.text
    error = few.json()["error"]
    assert error["field"] == "method.nodes"
    assert "greater than or equal to 9" in error["issues"][0]["message"]

    km_s = {"scenario": FOH, "overrides": {"initial_state": {"velocity_m_s": 7.3}}}
    answer = client.http.post("/v1/problems/validate", json=km_s)
    assert answer.status_code == 200, answer.text  # legal: warned, not refused
    (warning,) = answer.json()["warnings"]
    assert warning["field"] == "initial_state.velocity_m_s"
    assert warning["value"] == 7.3
    assert warning["plausible_min"] == 1000.0 and 12_000 < warning["plausible_max"] < 14_000
    assert "km/s" in warning["message"]

    job = client.submit(km_s)
    assert [w["field"] for w in job["warnings"]] == ["initial_state.velocity_m_s"]
    assert client.job(job["id"])["warnings"] == job["warnings"]
    result = _finished_result(client, job["id"])
    assert result["warnings"] == job["warnings"]
    failure = result["failure"]
    assert failure["code"] == "initial_guess"
    assert "initial_bank_deg" not in failure["message"]
    assert "initial_state.velocity_m_s" in failure["message"]
    assert failure["advice"][0].startswith("check the input first: initial_state.velocity_m_s")


def test_a_light_orbiter_is_told_its_mass_before_its_limits(client: ServiceClient) -> None:
    job = client.submit({"scenario": FOH, "overrides": {"vehicle": {"mass_kg": 104.305}}})
    assert [w["field"] for w in job["warnings"]] == ["vehicle"]  # m / (CD S) = 0.28 kg/m^2
    result = _finished_result(client, job["id"])
    assert result["status"] == "failed"
    advice = result["failure"]["advice"]
    assert advice[0].startswith("check the input first: vehicle: ballistic coefficient")
    assert "vehicle.mass_kg" in advice[0]
    assert any("load_factor" in hint for hint in advice[1:])  # the symptom, after its cause


def test_the_problem_as_solved_is_served_and_fingerprinted(
    api: ApiServer, client: ServiceClient, scenario: str, stack_env: dict[str, str]
) -> None:
    overrides = {"path_constraints": {"load_factor": {"max_g": 3.4}}}
    first = client.submit({"scenario": scenario, "overrides": overrides, "method": SMALL})
    result = _finished_result(client, first["id"])
    response = client.http.get(f"/v1/jobs/{first['id']}/problem")
    assert response.status_code == 200, response.text
    problem = response.json()
    assert problem["path_constraints"]["load_factor"]["max_g"] == 3.4
    provenance = result["provenance"]
    assert provenance["problem_sha256"] == _sha256(problem)
    assert provenance["scenario"] == {"name": scenario, "overrides": overrides, "method": SMALL}
    for library in (
        "numpy",
        "scipy",
        "clarabel",
        "cvxpy",
        "numba",
        "llvmlite",
        "ussa1976",
        "pymoo",
    ):
        assert provenance["packages"][library], library
    head = subprocess.run(
        ["git", "rev-parse", "HEAD"], cwd=REPO_ROOT, capture_output=True, text=True, check=True
    ).stdout.strip()
    assert provenance["software"]["version"] == "0.1.0"
    assert provenance["software"]["revision"].startswith(head)  # the worker runs this checkout

    warm = client.submit(
        {
            "scenario": scenario,
            "overrides": {"initial_guess": {"from_job": first["id"]}},
            "method": SMALL,
        }
    )
    warm_result = _finished_result(client, warm["id"])
    warm_problem = client.http.get(f"/v1/jobs/{warm['id']}/problem").json()
    assert warm_problem["initial_guess"]["from_job"] == first["id"]
    assert warm_problem["initial_guess"]["trajectory"]["time_s"]  # the copied trajectory
    assert warm_result["provenance"]["source_job"] == first["id"]
    assert warm_result["provenance"]["problem_sha256"] == _sha256(warm_problem)

    with TrajoptClient(api.base_url, api.api_key) as library:
        assert library.problem(first["id"]) == problem
    fetched = subprocess.run(
        [sys.executable, "-m", "app.cli", "problem", first["id"], "--server", api.base_url],
        cwd=REPO_ROOT,
        env={**stack_env, "TRAJOPT_API_KEY": api.api_key or ""},
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert fetched.returncode == 0, fetched.stderr
    assert json.loads(fetched.stdout) == problem
    assert f"sha256 {provenance['problem_sha256']}" in fetched.stderr

    other = ServiceClient(api.base_url, create_api_key(stack_env, "traceability-other"))
    try:
        refused = other.http.get(f"/v1/jobs/{first['id']}/problem")
        assert refused.status_code == 404
        assert refused.json()["error"]["code"] == "job_not_found"
    finally:
        other.close()
    with TrajoptClient(api.base_url, other.api_key) as stranger, pytest.raises(NotFoundError):
        stranger.problem(first["id"])
