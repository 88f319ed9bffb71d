"""The time-domain SCP of paper 002 ("foh-ptr") end to end on its built-in case-1 and case-2
scenarios and on the scenario with an active no-fly zone.

Acceptance figures: terminal velocity within 0.3 % of 971.03 m/s (independent NLP collocation,
801 nodes), converged within the default cap of 30 iterations, propagated terminal residuals
within Table 4's for 40 nodes, path limits within 1 % between nodes, the flown bank within its
80 deg between the nodes too, an active zone entered by at most 0.05 deg; recorded with the
commands in docs/methods/foh-ptr.md; the cap holds for each of the two starts (one per bank
sign). (The bound was 15 iterations, met by trajectories whose
bank turned to 180 deg between nodes held at 80 deg; within the limit case 1 takes 18 and 14 in
its two starts.)
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pytest

from app.schemas import ProblemDocument
from worker.solver.api import solve_problem
from worker.solver.methods import check_support
from worker.solver.methods.foh_ptr import method as foh_ptr
from worker.solver.problem import build_problem
from worker.solver.scenarios import get_scenario

REFERENCE_VF_M_S = 971.03
TABLE4_40_NODES = {  # paper 002 Table 4, proposed method, 40 nodes (rounded up)
    "altitude_m": 25.0,
    "longitude_deg": 0.05,
    "latitude_deg": 0.02,
    "velocity_m_s": 2.0,
    "flight_path_angle_deg": 0.05,
    "heading_deg": 0.1,
}


def _doc(name: str = "rlv-max-terminal-velocity", **method: Any) -> ProblemDocument:
    raw = dict(get_scenario(name).problem)
    raw["method"] = {**raw["method"], **method}
    return ProblemDocument.model_validate(raw)


@pytest.fixture(scope="module")
def adaptive() -> dict[str, Any]:
    return solve_problem(_doc(grid="adaptive"))


@pytest.fixture(scope="module")
def uniform() -> dict[str, Any]:
    return solve_problem(_doc(grid="uniform"))


def _kept(result: dict[str, Any]) -> list[dict[str, Any]]:
    """The history of the start whose answer is the result (every record without starts)."""
    starts = result.get("starts") or []
    chosen = next((s["start"] for s in starts if s["chosen"]), None)
    return [h for h in result["history"] if chosen is None or h["extra"]["start"] == chosen]


def test_converges_with_small_residuals(adaptive: dict[str, Any], uniform: dict[str, Any]) -> None:
    for result in (adaptive, uniform):
        assert all(s["iterations"] <= 30 for s in result["starts"]), result["starts"]
        bank = result["verification"]["control_limits"]["bank_deg"]
        assert bank["within"] and bank["max"] <= 80.0 * 1.01, bank
        assert all(h["conic_status"] == "optimal" for h in result["history"])
        assert _kept(result)[-1]["virtual_control_norm"] <= 1e-6
        err = result["verification"]["terminal_error_vs_optimized"]
        for key, bound in TABLE4_40_NODES.items():
            assert abs(err[key]) <= bound, (key, err[key])


def test_time_dilation_holds_in_every_subproblem(adaptive: dict[str, Any]) -> None:
    for h in adaptive["history"]:
        t = h["extra"]["node_times_s"]
        steps = [b - a for a, b in itertools.pairwise(t)]
        assert min(steps) >= 10.0 - 1e-6  # Delta_min (solver tolerance 1e-8 relative)
        assert max(steps) <= 150.0 + 1e-6  # Delta_max
        assert t[-1] == pytest.approx(1600.0, abs=1e-6)  # sum s_k = t_f
        assert h["extra"]["max_interval_change_s"] <= 50.0 + 1e-6  # DeltaT_max


def test_both_grids_are_feasible_between_nodes(
    adaptive: dict[str, Any], uniform: dict[str, Any]
) -> None:
    """Acceptance: heat rate, dynamic pressure and load factor within 1 % of their limits
    everywhere between nodes (the verification samples 20 points per interval of the DOP853
    propagation of the optimized bank)."""
    for result in (adaptive, uniform):
        ver = result["verification"]
        for entry in ver["path_maxima"].values():
            assert entry["ratio"] <= 1.01
        assert ver["feasible"]


def test_node_only_limits_leave_the_heat_peak_between_nodes() -> None:
    """Without the between-node rows (the paper's node-only limits) the heat-rate peak falls
    between two nodes, beyond the 1 % the acceptance allows: the rows, not luck, keep the
    solution feasible."""
    result = solve_problem(_doc(grid="adaptive", intersample_constraints=False))
    assert result["verification"]["path_maxima"]["heat_rate_W_m2"]["ratio"] > 1.01


def test_terminal_velocity_matches_reference(
    adaptive: dict[str, Any], uniform: dict[str, Any]
) -> None:
    """Acceptance: within 0.3 % of the 801-node collocation optimum, on each grid. 40 nodes give
    the bank fewer degrees of freedom, so the value may only fall short of the reference by that
    much (measured 968.53 and 968.52 m/s with the bank held within its limit between the nodes;
    969.3 and 969.2 before, when it turned to 180 deg there); above it would mean a defect or a
    violated limit."""
    for result in (adaptive, uniform):
        vf = result["objective"]["value"]
        assert REFERENCE_VF_M_S * (1.0 - 0.003) <= vf <= REFERENCE_VF_M_S + 0.5, vf


def test_first_order_step_stops_short() -> None:
    """The paper's first-order PTR step (second_order false) with its damping ends short of the
    optimum, on a point the SQP step improves on by about 3 %: the curvature term is what reaches
    the reference. (It used to converge there; with the bank held within its limit between the
    nodes it creeps on and runs out of its 30 iterations at 942 m/s, still short.)"""
    result = solve_problem(
        _doc(
            grid="uniform",
            second_order=False,
            weight_nonlinear=1.0e4,
            weight_trust_region_min=0.02,
            trust_defect_target=0.3,
            trust_factor=2.0,
            max_iterations=30,
        )
    )
    assert result["status"] == "succeeded" or result["failure"]["code"] == "max_iterations"
    assert result["objective"]["value"] < REFERENCE_VF_M_S * (1.0 - 0.02)
    assert not any(h["extra"]["second_order_step"] for h in result["history"])


def test_printed_case_2_zone_is_not_active() -> None:
    """Case 2 as printed: measured as paper 002 eq. 27 does (metric lat_lon) the zone stays clear
    of the optimal path, so the terminal velocity is case 1's (within the same 0.3 %)."""
    result = solve_problem(_doc("rlv-max-terminal-velocity-nfz"))
    assert result["status"] == "succeeded", result.get("failure")
    (zone,) = result["verification"]["no_fly_zones"]
    assert zone["min_clearance_deg"] > 0.1
    assert abs(result["objective"]["value"] / REFERENCE_VF_M_S - 1.0) <= 0.003


def test_support_check_refuses_what_it_cannot_do() -> None:
    raw = dict(get_scenario("rlv-max-terminal-velocity").problem)
    raw["objective"] = "min_time"
    raw["waypoints"] = [
        {"latitude_deg": 30, "longitude_deg": 0, "radius_deg": 1, "order": 0},
    ]
    issues = {i.field for i in check_support(ProblemDocument.model_validate(raw))}
    assert {"objective.terms[0].name", "waypoints"} <= issues
    assert check_support(_doc()) == []


def test_active_zone_is_respected_between_nodes() -> None:
    """Acceptance: with a zone on the case-1 path, the propagated trajectory (DOP853, 20 samples
    per interval) enters it by no more than 0.05 deg of arc."""
    result = solve_problem(_doc("rlv-max-terminal-velocity-active-nfz"))
    assert result["status"] == "succeeded", result.get("failure")
    (zone,) = result["verification"]["no_fly_zones"]
    assert zone["min_clearance_deg"] >= -0.05


def test_a_guess_that_reaches_the_ground_fails_the_job_with_the_reason() -> None:
    """A constant bank of -40 deg spirals down before 1600 s: the method cannot start, which is a
    failed job naming the option, not an internal error."""
    result = solve_problem(_doc(initial_bank_deg=-40.0))
    assert result["status"] == "failed"
    assert result["failure"]["code"] == "initial_guess"
    assert "method.initial_bank_deg" in result["failure"]["message"]
    assert result["history"] == []


def _run_case_1() -> Any:
    """Case 1 through the method itself (``methods.foh_ptr.method.run``), adaptive grid."""
    doc = _doc(grid="adaptive")
    return foh_ptr.run(build_problem(doc), doc.method)


def test_helper_thread_changes_nothing_but_time(monkeypatch: pytest.MonkeyPatch) -> None:
    """With a second CPU the curvature runs on the helper thread beside the maps; in line it is
    the same function of the same inputs, so the iterates are identical, not merely close."""
    overlapped = _run_case_1()
    monkeypatch.setattr(foh_ptr.side_thread, "available", lambda: False)
    in_line = _run_case_1()
    assert overlapped.status == in_line.status == "converged"
    assert len(overlapped.history) == len(in_line.history)
    a, b = overlapped.trajectory, in_line.trajectory
    assert np.array_equal(a.y, b.y) and np.array_equal(a.t, b.t) and np.array_equal(a.bank, b.bank)


def test_a_rejected_step_returns_to_its_reference_and_the_loop_goes_on(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A step whose linearization is not finite is recorded as rejected, the loop goes back to
    the reference that made it (discarding the curvature started for the rejected one) and
    still converges, to within 0.1 % of the run without the rejection (measured 0.07 %: the
    rejection changes the iterates' path, not the answer). Rejection is forced once, at the
    third step's check."""
    plain = _run_case_1().objective_terms["max_terminal_velocity"]
    checks = itertools.count(1)
    real = foh_ptr.finite
    monkeypatch.setattr(foh_ptr, "finite", lambda data: next(checks) != 3 and real(data))
    out = _run_case_1()
    rejected = [r for r in out.history if "rejected" in r.extra]
    assert [r.iteration for r in rejected] == [3]
    assert out.status == "converged"
    vf = out.objective_terms["max_terminal_velocity"]
    assert abs(vf / plain - 1.0) <= 0.001, (vf, plain)
