"""The physical pre-checks: each one on a problem it must name, and on one it must leave alone.

The figures are the solver's own flights: full lift-up from paper 000's entry point peaks at
792 kW/m^2 in its exponential atmosphere and at 1 108 kW/m^2 in the US76 one (an NLP that
minimizes the peak over every bank profile agrees to 0.01 %, bench/lift_up_bound.py). The
user's problem flies paper 002's vehicle from 10 E, 5 N to 30 E, 55 N (5 848 km): constant-bank
flights that end at that distance last 1 200-1 281 s, and the problem solves at 1 300 s.
"""

from __future__ import annotations

import copy
from typing import Any

import pytest

from app.schemas import ProblemDocument
from worker.solver.failure_causes import name_causes, with_methods
from worker.solver.prechecks import likely_causes, proven_infeasible
from worker.solver.prechecks.reach import reach_findings
from worker.solver.problem import EntryProblem, build_problem
from worker.solver.scenarios import get_scenario


def _model(doc: dict[str, Any]) -> EntryProblem:
    return build_problem(ProblemDocument.model_validate(doc))


def _energy(**changes: Any) -> dict[str, Any]:
    doc = copy.deepcopy(get_scenario("rlv-min-heat-load").problem)
    if changes.pop("us76", False):
        doc["planet"]["atmosphere"] = {"model": "us76"}
    if "heat_limit" in changes:
        doc["path_constraints"]["heat_rate"]["max_W_m2"] = changes.pop("heat_limit")
    assert not changes
    return doc


def _user(
    final_time_s: float = 1300.0, target: tuple[float, float] = (30.0, 55.0)
) -> dict[str, Any]:
    """Paper 002's vehicle from a moved entry point to a target of the user's own."""
    doc = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    doc["initial_state"].update(
        longitude_deg=10, latitude_deg=5, altitude_m=95000, velocity_m_s=7300, heading_deg=20
    )
    doc["terminal"] = {
        "altitude_m": 25000,
        "longitude_deg": target[0],
        "latitude_deg": target[1],
        "velocity_m_s": {"kind": "free"},
        "flight_path_angle_deg": {"kind": "free"},
        "heading_deg": {"kind": "free"},
    }
    doc["final_time"] = {"kind": "fixed", "value_s": final_time_s}
    doc["objective"] = "min_heat_load"
    return doc


def test_a_heat_limit_below_the_lift_up_peak_is_proven_out_of_reach() -> None:
    findings, pull_up = proven_infeasible(_model(_energy(us76=True)))
    assert pull_up is not None
    assert 1.100e6 < pull_up.peaks["heat_rate_W_m2"].value < 1.115e6
    (finding,) = findings
    assert finding.proven and finding.check == "limit_below_pull_up"
    assert finding.field == "path_constraints.heat_rate.max_W_m2"
    assert (finding.limit, finding.units) == (1.0e6, "W/m^2")
    assert "1 000 kW/m^2" in finding.message and "1 108 kW/m^2" in finding.message
    assert "full lift-up" in finding.message and "no bank profile can hold it" in finding.message
    assert "path_constraints.heat_rate.max_W_m2 above 1.108e+06" in finding.advice


def test_the_same_limit_in_the_exponential_atmosphere_is_not_refused() -> None:
    findings, pull_up = proven_infeasible(_model(_energy()))
    assert findings == []
    assert pull_up is not None and 0.79e6 < pull_up.peaks["heat_rate_W_m2"].value < 0.80e6


def test_a_limit_within_the_margin_is_a_likely_cause_not_a_proof() -> None:
    """790 kW/m^2 is 0.3 % below the 792 kW/m^2 peak: within what the verification tolerates
    and the bound's own error, so it is named after a failure but never refuses."""
    model = _model(_energy(heat_limit=7.9e5))
    assert proven_infeasible(model)[0] == []
    (finding,) = [f for f in likely_causes(model) if f.check == "limit_below_pull_up"]
    assert not finding.proven and "likely out of reach" in finding.message


def test_an_optimized_angle_of_attack_names_the_cause_but_proves_nothing() -> None:
    """Paper 003's vehicle flies its angle of attack: a held attitude bounds nothing, so even a
    limit far below its peak (about 1 430 kW/m^2) is only named."""
    doc = copy.deepcopy(get_scenario("rlv-min-time-hp").problem)
    doc["path_constraints"]["heat_rate"]["max_W_m2"] = 1.0e6
    model = _model(doc)
    assert proven_infeasible(model) == ([], None)
    (finding,) = [f for f in likely_causes(model) if f.check == "limit_below_pull_up"]
    assert not finding.proven and "angle of attack held at" in finding.message


def test_a_reachable_target_at_a_fitting_final_time_is_not_flagged() -> None:
    assert reach_findings(_model(_user())) == []


def test_a_final_time_far_from_the_flight_to_the_target_is_named_with_its_figures() -> None:
    """Beyond the longest flight's duration (full lift-up, about 1 800 s) the final time is the
    likely cause."""
    (finding,) = reach_findings(_model(_user(final_time_s=2100.0)))
    assert (finding.check, finding.field, finding.proven, finding.possible) == (
        "final_time",
        "final_time.value_s",
        False,
        False,
    )
    assert finding.value == 2100.0 and 1250.0 < (finding.limit or 0.0) < 1310.0
    assert "the final time 2100 s is longer than the flight needs" in finding.message
    assert "5 848 km" in finding.message and "the longest flight found lasts 1796 s" in (
        finding.message
    )
    assert "final_time.value_s near" in finding.advice and '"kind": "free"' in finding.advice
    assert finding.as_cause()["likely"] is True


def test_a_final_time_a_wandering_flight_may_last_is_only_a_possible_cause() -> None:
    """1 500 s: longer than the flights that end at the target (1 250-1 310 s) but within the
    longest flight's 1 796 s, so a flight with S-turns may last it (the NLP finds such user
    problems feasible): named as possible, advice kept."""
    (finding,) = reach_findings(_model(_user(final_time_s=1500.0)))
    assert finding.possible and not finding.proven and finding.as_cause()["likely"] is False
    assert "the final time 1500 s is longer than flights that end at the target take" in (
        finding.message
    )
    assert "may not exist" in finding.message
    assert "final_time.value_s near" in finding.advice


def test_a_possible_cause_does_not_call_a_failed_run_infeasible() -> None:
    """A run that diverged keeps its code when the only cause found is possible; its message
    adds the cause as possible."""
    doc = ProblemDocument.model_validate(_user(final_time_s=1500.0))
    result = {
        "status": "failed",
        "failure": {"code": "diverged", "message": "diverged at iteration 9"},
    }
    advice = name_causes(result, build_problem(doc), None, doc)
    failure = result["failure"]
    assert failure["code"] == "diverged"
    assert failure["message"].startswith("diverged at iteration 9; possible cause: the final time")
    assert failure["cause"]["likely"] is False and advice


@pytest.mark.parametrize(
    ("target", "words"),
    [((120.0, 40.0), "the longest flight found (full lift-up) covers"), ((12.0, 10.0), "too near")],
)
def test_an_unreachable_target_is_named_with_its_distance(
    target: tuple[float, float], words: str
) -> None:
    findings = reach_findings(_model(_user(target=target)))
    (finding,) = [f for f in findings if f.check == "target_out_of_reach"]
    assert finding.field == "terminal.longitude_deg, terminal.latitude_deg"
    assert words in finding.message and "likely" in finding.message
    assert f"({target[0]:.2f} E, {target[1]:.2f} N)" in finding.message


def test_a_zone_across_the_corridor_is_named_and_one_beside_it_is_not() -> None:
    """A 1 500 km zone 1 725 km ahead takes a track 55 deg aside to pass; no bank turns a
    vehicle at 7 km/s more than about 16 deg that far out. The 300 km zone of the user's own
    problem lies beside the direct path."""
    blocked = _user()
    blocked["no_fly_zones"] = [
        {"name": "wall", "center_latitude_deg": 20, "center_longitude_deg": 14, "radius_km": 1500}
    ]
    (finding,) = [f for f in reach_findings(_model(blocked)) if f.check == "zone_blocks_corridor"]
    assert finding.field == "no_fly_zones[0]" and "'wall'" in finding.message
    assert "likely blocks the whole corridor" in finding.message
    beside = _user()
    beside["no_fly_zones"] = [
        {"center_latitude_deg": 30, "center_longitude_deg": 21, "radius_km": 300}
    ]
    assert [f for f in reach_findings(_model(beside)) if f.check == "zone_blocks_corridor"] == []


def test_a_final_time_cause_names_the_methods_that_take_a_free_final_time() -> None:
    """foh-ptr needs a fixed final time; of the methods, cheb-scvx takes the user's problem
    with a free one (energy-scp wants no bank-rate limit, hp-scp and lgl-sqp an optimized angle
    of attack): the advice names it."""
    doc = ProblemDocument.model_validate(_user(final_time_s=1500.0))
    (finding,) = reach_findings(build_problem(doc))
    advice = with_methods(finding, doc).advice
    assert advice.endswith(
        '(final_time: {"kind": "free"}) with a method that takes it: foh-ptr, cheb-scvx'
    )
