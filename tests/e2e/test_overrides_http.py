"""A scenario's atmosphere switched by overrides, through a real ``trajopt serve`` (embedded mode).

The switch is checked where it ends up: the normalized problem ``/v1/problems/validate``
returns, the problem stored with the job, and the solver's trajectory, whose dynamic pressure
follows the U.S. Standard Atmosphere 1976 and not the scenario's exponential one.
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.integration.harness import SCENARIO, US76_FEASIBLE, ServiceClient
from worker.solver.atmosphere import ExponentialAtmosphere, US76Atmosphere

pytestmark = pytest.mark.slow

US76 = {"planet": {"atmosphere": {"model": "us76"}}}


@pytest.fixture
def client(embedded_client: ServiceClient) -> ServiceClient:
    return embedded_client


@pytest.fixture
def data_dir(embedded_data_dir: Path) -> Path:
    return embedded_data_dir


def _stored_problem(data_dir: Path, job_id: str) -> dict[str, Any]:
    """The problem document the service stored with the job (its SQLite row)."""
    with sqlite3.connect(data_dir / "trajopt.sqlite3") as connection:
        row = connection.execute("SELECT problem FROM jobs WHERE id = ?", (job_id,)).fetchone()
    assert row is not None, job_id
    problem: dict[str, Any] = json.loads(row[0]) if isinstance(row[0], str) else row[0]
    return problem


def test_validate_switches_the_atmosphere_and_names_bad_fields(client: ServiceClient) -> None:
    scenario = client.http.get(f"/v1/scenarios/{SCENARIO}").json()
    assert scenario["problem"]["planet"]["atmosphere"]["model"] == "exponential"

    response = client.http.post(
        "/v1/problems/validate", json={"scenario": SCENARIO, "overrides": US76}
    )
    assert response.status_code == 200, response.text
    assert response.json()["problem"]["planet"]["atmosphere"] == {"model": "us76"}

    bad = {"planet": {"atmosphere": {"model": "us76", "scale_height_m": 8000}}}
    response = client.http.post(
        "/v1/problems/validate", json={"scenario": SCENARIO, "overrides": bad}
    )
    assert response.status_code == 422, response.text
    error = response.json()["error"]
    assert (error["code"], error["field"]) == (
        "invalid_problem",
        "planet.atmosphere.scale_height_m",
    )
    assert [i["code"] for i in error["issues"]] == ["extra_forbidden"]

    response = client.http.post(
        "/v1/problems/validate", json={"scenario": SCENARIO, "overrides": [US76]}
    )
    assert response.status_code == 422, response.text
    assert response.json()["error"]["field"] == "overrides"


def test_job_is_stored_and_solved_with_us76(client: ServiceClient, data_dir: Path) -> None:
    overrides = {**US76_FEASIBLE, "method": {"nodes": 41, "max_iterations": 5}}
    job = client.submit({"scenario": SCENARIO, "overrides": overrides})
    stored = _stored_problem(data_dir, job["id"])
    assert stored["planet"]["atmosphere"] == {"model": "us76"}
    assert stored["method"]["nodes"] == 41

    done = client.wait_finished(job["id"])
    assert done["status"] in ("succeeded", "failed"), done
    result = client.http.get(f"/v1/jobs/{job['id']}/result").json()
    assert result["provenance"]["method_options"]["nodes"] == 41
    trajectory = result["trajectory"]
    altitude = np.asarray(trajectory["altitude_m"])
    speed = np.asarray(trajectory["velocity_m_s"])
    density = 2.0 * np.asarray(trajectory["dynamic_pressure_Pa"]) / speed**2
    us76, _ = US76Atmosphere().density(altitude)
    np.testing.assert_allclose(density, us76, rtol=1e-9)
    own = client.http.get(f"/v1/scenarios/{SCENARIO}").json()["problem"]["planet"]["atmosphere"]
    exponential, _ = ExponentialAtmosphere(
        rho0=own["density_sea_level_kg_m3"], scale_height_m=own["scale_height_m"]
    ).density(altitude)
    assert np.median(np.abs(density / exponential - 1.0)) > 0.1


def test_an_infeasible_heat_limit_fails_at_once_naming_the_limit_and_the_peak(
    client: ServiceClient,
) -> None:
    """The scenario in the US76 atmosphere: full lift-up flight from its entry point already
    peaks at 1 108 kW/m^2 in the first pull-up, above its 1 000 kW/m^2 limit, and no bank
    profile flies lower. The job fails ``infeasible`` before any iteration, naming the limit,
    the peak and the field to raise (instead of diverging after ten iterations)."""
    job = client.submit({"scenario": SCENARIO, "overrides": US76})
    done = client.wait_finished(job["id"])
    assert (done["status"], done["error"]["code"]) == ("failed", "infeasible"), done
    message = done["error"]["message"]
    assert "heat-rate limit 1 000 kW/m^2 is below the first heat-rate peak" in message
    assert "full lift-up flight, 1 108 kW/m^2" in message
    result = client.http.get(f"/v1/jobs/{job['id']}/result").json()
    cause = result["failure"]["cause"]
    assert cause["field"] == "path_constraints.heat_rate.max_W_m2" and cause["proven"] is True
    assert cause["limit"] == 1.0e6 and 1.10e6 < cause["value"] < 1.115e6
    assert result["failure"]["advice"][0].startswith(
        "raise path_constraints.heat_rate.max_W_m2 above 1.108e+06"
    )
    assert result["history"] == [] and result["timing"]["iterations"] == 0


def test_the_readme_override_example_solves(client: ServiceClient) -> None:
    """README.md's example of overrides: paper 002's case in the US76 atmosphere on 60 nodes
    succeeds, verified (947.69 m/s)."""
    overrides = {"method": {"nodes": 60}, "planet": {"atmosphere": {"model": "us76"}}}
    job = client.submit({"scenario": "rlv-max-terminal-velocity", "overrides": overrides})
    done = client.wait_finished(job["id"], timeout=300)
    assert done["status"] == "succeeded", done
    result = client.http.get(f"/v1/jobs/{job['id']}/result").json()
    assert result["verification"]["feasible"] is True
    assert abs(result["objective"]["value"] - 947.69) < 0.01
