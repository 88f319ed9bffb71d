"""The energy-domain SCP (paper 000) on its built-in scenario, and how it fails.

Acceptance figures come from the reference solution in the issue: heat load 731.01 MJ/m^2 from
an independent NLP collocation solve (961 nodes, IPOPT, re-integrated at 1e-12).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest

from app.schemas import ProblemDocument
from worker.solver.api import solve_problem
from worker.solver.conic import ConeProblem, ConicSolution, ConicStatus, make_backend
from worker.solver.methods.energy_scp.method import run as run_energy_scp
from worker.solver.problem import build_problem
from worker.solver.scenarios import get_scenario
from worker.solver.verification import verify

REFERENCE_HEAT_LOAD_J_M2 = 731.01e6


def _doc(**method: Any) -> ProblemDocument:
    raw = dict(get_scenario("rlv-min-heat-load").problem)
    raw["method"] = {**raw["method"], **method}
    return ProblemDocument.model_validate(raw)


@pytest.fixture(scope="module")
def solved() -> dict[str, Any]:
    return solve_problem(_doc())


def test_scenario_meets_acceptance(solved: dict[str, Any]) -> None:
    assert solved["status"] == "succeeded", solved["failure"]
    # heat load within 0.15 % of the reference, both as optimized and as propagated (the
    # relaxed trust weight and the stationarity test reach 0.05 %; the paper's fixed weights
    # stopped 0.29 % short in 8 iterations)
    assert abs(solved["objective"]["value"] / REFERENCE_HEAT_LOAD_J_M2 - 1) <= 0.0015
    assert abs(solved["objective"]["propagated_value"] / REFERENCE_HEAT_LOAD_J_M2 - 1) <= 0.0015
    ver = solved["verification"]
    assert ver["feasible"]
    err = {k: abs(v["error"]) for k, v in ver["terminal_error_vs_target"].items()}
    assert err["altitude_m"] <= 500.0
    assert err["longitude_deg"] <= 0.1 and err["latitude_deg"] <= 0.1
    assert err["flight_path_angle_deg"] <= 0.3 and err["heading_deg"] <= 0.3
    for entry in ver["path_maxima"].values():
        assert entry["ratio"] <= 1.01  # limits respected between nodes within 1%
    # the stationarity test costs iterations: 24 today, within the default cap of 60
    assert solved["timing"]["iterations"] <= 30


def test_result_document_shape(solved: dict[str, Any]) -> None:
    traj = solved["trajectory"]
    for column in (
        "time_s",
        "altitude_m",
        "longitude_deg",
        "latitude_deg",
        "velocity_m_s",
        "flight_path_angle_deg",
        "heading_deg",
        "bank_deg",
        "alpha_deg",
        "heat_rate_W_m2",
        "dynamic_pressure_Pa",
        "load_factor_g",
    ):
        assert len(traj[column]) == traj["nodes"] == 121
        assert column in traj["units"]
    assert traj["altitude_m"][0] == pytest.approx(105e3)
    assert traj["altitude_m"][-1] == pytest.approx(30e3, abs=1e-6)
    assert max(abs(b) for b in traj["bank_deg"]) <= 80.0 + 1e-6
    history = solved["history"]
    assert [h["iteration"] for h in history] == list(range(1, len(history) + 1))
    for key in (
        "cost",
        "cost_terms",
        "max_state_change",
        "trust_region_slack",
        "virtual_control_norm",
        "linearization_error",
        "nodes_post_corrected",
        "relaxation_gap",
        "conic_status",
        "conic_solve_s",
        "iteration_wall_s",
    ):
        assert key in history[-1]
    # the control cone is tight at the solution (|u| = 1 to 1e-3): the relaxation is exact
    assert history[-1]["relaxation_gap"] <= 1e-3
    assert solved["provenance"]["packages"]["clarabel"]


def test_verification_catches_a_perturbed_control() -> None:
    """Adding 10 degrees of bank over the last third must break the terminal conditions."""
    doc = _doc()
    model = build_problem(doc)
    outcome = run_energy_scp(model, doc.method)
    traj = outcome.trajectory
    assert traj is not None
    assert verify(model, traj)["feasible"]
    k = traj.bank.size
    traj.bank[2 * k // 3 :] += math.radians(10.0)
    report = verify(model, traj)
    assert not report["feasible"]
    assert not all(v["within"] for v in report["terminal_error_vs_target"].values())


@dataclass
class RecordingBackend:
    """Wraps a backend and keeps every subproblem it was given."""

    inner: Any
    name: str = "recording"
    problems: list[ConeProblem] = field(default_factory=list)

    def solve(self, problem: ConeProblem, *, time_limit_s: float | None = None) -> ConicSolution:
        self.problems.append(problem)
        return self.inner.solve(problem, time_limit_s=time_limit_s)


def test_direct_and_cvxpy_backends_agree_on_an_entry_subproblem() -> None:
    """Same SOCP through Clarabel directly and through cvxpy: costs agree to 1e-6 relative
    (both interior-point solves stop at ~1e-8 relative gap)."""
    doc = _doc(max_iterations=3)
    model = build_problem(doc)
    recorder = RecordingBackend(make_backend("clarabel"))
    run_energy_scp(model, doc.method, backend=recorder)
    sub = recorder.problems[-1]
    direct = make_backend("clarabel").solve(sub)
    via_cvxpy = make_backend("cvxpy:CLARABEL").solve(sub)
    assert direct.status == via_cvxpy.status == ConicStatus.OPTIMAL
    assert direct.objective is not None and via_cvxpy.objective is not None
    assert abs(direct.objective - via_cvxpy.objective) <= 1e-6 * abs(direct.objective)


class FailingBackend:
    """Solves normally, then reports numerical trouble from iteration ``fail_at`` on."""

    name = "failing"

    def __init__(self, fail_at: int) -> None:
        self.inner = make_backend("clarabel")
        self.calls = 0
        self.fail_at = fail_at

    def solve(self, problem: ConeProblem, *, time_limit_s: float | None = None) -> ConicSolution:
        self.calls += 1
        if self.calls >= self.fail_at:
            return ConicSolution(
                None, ConicStatus.NUMERICAL_ERROR, "NumericalError", None, 0.0, 0, 0.0, "failing"
            )
        return self.inner.solve(problem, time_limit_s=time_limit_s)


def test_conic_failure_ends_failed_with_history() -> None:
    doc = _doc()
    model = build_problem(doc)
    outcome = run_energy_scp(model, doc.method, backend=FailingBackend(fail_at=3))
    assert outcome.status == "failed"
    assert outcome.failure_code == "numerical_error"
    assert len(outcome.history) == 2


def test_iteration_cap_gives_failed_result_with_history_not_an_exception() -> None:
    result = solve_problem(_doc(max_iterations=2))
    assert result["status"] == "failed"
    assert result["failure"]["code"] == "max_iterations"
    assert len(result["history"]) == 2
    assert result["trajectory"] is not None and result["verification"] is not None


def test_impossible_path_limits_fail_with_reason() -> None:
    raw = dict(get_scenario("rlv-min-heat-load").problem)
    raw["path_constraints"] = {
        **raw["path_constraints"],
        "heat_rate": {"max_W_m2": 1e3, "k_q": 9.4369e-5},
    }
    doc = ProblemDocument.model_validate(raw)
    result = solve_problem(doc, prechecks=False)  # the method's own refusal
    assert result["status"] == "failed"
    assert result["failure"]["code"] == "path_limits_infeasible"
    refused = solve_problem(doc)  # the pre-check's, before the method: the same cause, proven
    assert (refused["status"], refused["failure"]["code"]) == ("failed", "infeasible")
    assert refused["failure"]["cause"]["field"] == "path_constraints.heat_rate.max_W_m2"
    assert refused["failure"]["cause"]["proven"] is True


def test_cancel_and_time_limit_keep_history() -> None:
    seen: list[dict[str, Any]] = []
    result = solve_problem(_doc(), on_iteration=seen.append, should_stop=lambda: len(seen) >= 2)
    assert result["status"] == "cancelled"
    assert len(result["history"]) == 2 == len(seen)
    timed = solve_problem(_doc(time_limit_s=1e-6))
    assert timed["status"] == "timed_out"
    assert timed["failure"]["code"] == "time_limit"


def test_uniform_grid_of_the_paper_is_available() -> None:
    doc = _doc(grid="uniform")
    model = build_problem(doc)
    outcome = run_energy_scp(model, doc.method)
    assert outcome.status == "converged"
    assert np.allclose(np.diff(outcome.trajectory.grid), np.diff(outcome.trajectory.grid)[0])
