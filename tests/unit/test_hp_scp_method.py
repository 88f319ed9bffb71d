"""The pseudospectral method (paper 003) through the solver's front door: an unconverged run
ends as a failed result with its reason and its whole history, never as a success; the result
flies the attitude polynomials and reports the angle-of-attack checks."""

from __future__ import annotations

import copy

import pytest

from app.schemas import ProblemDocument
from worker.solver.api import solve_problem
from worker.solver.scenarios import get_scenario


@pytest.fixture(scope="module")
def short_run() -> dict:
    raw = copy.deepcopy(get_scenario("rlv-min-time-hp").problem)
    # the paper's constant-control guess, as its scenario pins it: four iterations from it
    # leave virtual control
    raw["method"] = {
        "name": "hp-scp",
        "guess": "propagated",
        "nodes": 41,
        "intervals": 8,
        "max_iterations": 4,
    }
    return solve_problem(ProblemDocument.model_validate(raw))


@pytest.mark.slow
def test_an_unconverged_run_is_a_failed_result_with_its_history(short_run: dict) -> None:
    assert short_run["status"] == "failed"
    # four iterations from the guess leave virtual control: reported as an infeasible stop
    assert short_run["failure"]["code"] == "infeasible"
    assert "not converged in 4 iterations" in short_run["failure"]["message"]
    history = short_run["history"]
    assert [r["iteration"] for r in history] == [1, 2, 3, 4]
    for record in history:
        assert record["extra"]["mesh_points"] == 41
        assert "trust_weight" in record["extra"] and "corrections" in record["extra"]
        assert record["cost_terms"]["min_time"] == pytest.approx(
            record["cost_terms"]["final_time_s"]
        )


@pytest.mark.slow
def test_the_result_checks_the_flown_angle_of_attack(short_run: dict) -> None:
    """The verification flies the mesh's polynomials and checks alpha against its bounds and
    rate limit (the scenario's [0, 40] deg and 2 deg/s) as well as the bank."""
    limits = short_run["verification"]["control_limits"]
    assert {
        "bank_deg",
        "bank_rate_deg_s",
        "alpha_max_deg",
        "alpha_min_deg",
        "alpha_rate_deg_s",
    } <= (set(limits))
    assert limits["alpha_max_deg"]["limit"] == 40.0
    assert limits["alpha_min_deg"]["limit"] == 0.0
    assert limits["alpha_rate_deg_s"]["limit"] == pytest.approx(2.0)
