"""Auto's cross-check: on by default where local optima are known (objectives on the final
latitude or longitude, heat loads whose answer skips), and run on past a method that fails
until one gives a second verified value. Pure logic: the methods are replaced by a function
that returns fixed outcomes."""

from __future__ import annotations

import copy
from typing import Any

from app.schemas import ProblemDocument
from worker.solver.auto.local_optima import cross_check_wanted
from worker.solver.auto.runner import AutoRun, _cross_check
from worker.solver.methods.selection import select
from worker.solver.scenarios import get_scenario


def _document(scenario: str, method: dict[str, Any], heading_deg: float | None = None) -> Any:
    document = copy.deepcopy(get_scenario(scenario).problem)
    document["method"] = method
    if heading_deg is not None:
        document["initial_state"]["heading_deg"] = heading_deg
    return ProblemDocument.model_validate(document)


def _flight(altitudes_km: list[float]) -> dict[str, Any]:
    return {"trajectory": {"altitude_m": [1000.0 * h for h in altitudes_km]}}


UNDULATING = _flight([105, 95, 88, 92, 87, 81, 83, 74, 60, 30])
"""Paper 000's heat-load optimum in outline: climbs of 4 km at most."""
SKIPPING = _flight([111, 97, 72, 66, 72, 82, 78, 58, 62, 27])
"""A skipping heat-load answer in outline: 16 km up from its first low point."""


def test_the_default_cross_checks_range_objectives_and_skipping_heat_loads() -> None:
    assert cross_check_wanted(_document("shuttle-max-crossrange", {}))  # max_final_latitude
    heat_load = _document("rlv-min-heat-load", {})
    assert not cross_check_wanted(heat_load)
    assert not cross_check_wanted(heat_load, UNDULATING)
    assert cross_check_wanted(heat_load, SKIPPING)
    assert not cross_check_wanted(heat_load, {"trajectory": None})
    assert not cross_check_wanted(_document("shuttle-max-crossrange", {"cross_check": False}))
    assert not cross_check_wanted(_document("rlv-min-heat-load", {"cross_check": False}), SKIPPING)
    assert cross_check_wanted(_document("rlv-min-heat-load", {"cross_check": True}))


def _outcome(name: str) -> dict[str, Any]:
    """What each method gives here: the answer's method a worse optimum, the next one nothing
    verified, the one after the better optimum."""
    objective = {"name": "max_final_latitude", "units": "deg"}
    if name == "foh-ptr":
        return {
            "status": "succeeded",
            "history": [{"iteration": 1}],
            "objective": {**objective, "value": 62.40},
        }
    if name == "cheb-scvx":
        return {
            "status": "failed",
            "history": [{"iteration": 1}],
            "failure": {"code": "max_iterations"},
            "objective": {**objective, "value": 48.1},
        }
    return {
        "status": "succeeded",
        "history": [{"iteration": 1}],
        "objective": {**objective, "value": 63.906},
    }


def test_a_cross_check_runs_past_a_failed_method_to_a_second_verified_value() -> None:
    problem = _document("shuttle-max-crossrange", {}, heading_deg=60.0)
    selection = select(problem)
    names = [c.name for c in selection.candidates]
    assert names == ["foh-ptr", "cheb-scvx", "hp-scp", "lgl-sqp"], names
    ran: list[str] = []

    def solve_one(document: ProblemDocument, **hooks: Any) -> dict[str, Any]:
        ran.append(document.method.name)
        return _outcome(document.method.name)

    run = AutoRun(problem, solve_one, {})
    kept = run.run("foh-ptr", selection.candidates[0].options, "answer")
    assert kept is not None and kept.succeeded
    entry = _cross_check(run, kept, selection)
    assert ran == ["foh-ptr", "cheb-scvx", "hp-scp"]
    assert entry["methods"] == ["foh-ptr", "hp-scp"]
    assert entry["agree"] is False and "2.36 % apart" in entry["warning"]
