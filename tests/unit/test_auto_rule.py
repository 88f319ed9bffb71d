"""Auto's rule as pure logic: which methods accept which documents and in which order, the 422
of a document none accepts, the capability matrix, and how attempts are weighed."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest

from app.caps import cap_issues
from app.schemas import AutoOptions, ProblemDocument
from app.settings import Settings
from worker.solver.auto.outcome import (
    Attempt,
    advice_for_auto,
    better,
    compare,
    failure_of_none,
    most_informative,
)
from worker.solver.methods import METHODS, check_support, list_methods
from worker.solver.methods.capabilities import capability_matrix, matrix_table
from worker.solver.methods.selection import PREFERENCE, select
from worker.solver.scenarios import get_scenario, list_scenarios

DOCS = Path(__file__).resolve().parents[2] / "docs"


def _auto(scenario: str, method: dict[str, Any] | None = None, **changes: Any) -> ProblemDocument:
    """``scenario``'s problem with ``changes`` at top level and auto (with ``method``) as its
    method."""
    document = copy.deepcopy(get_scenario(scenario).problem)
    document.update(changes)
    document["method"] = {"name": "auto", **(method or {})}
    return ProblemDocument.model_validate(document)


def _candidates(doc: ProblemDocument) -> list[str]:
    return [c.name for c in select(doc).candidates]


def test_the_order_places_every_method_once() -> None:
    assert sorted(p.name for p in PREFERENCE) == sorted(METHODS)


@pytest.mark.parametrize(
    ("scenario", "changes", "expected"),
    [
        # energy-scp's own class: free final time, a scheduled angle of attack, soft targets
        ("rlv-min-heat-load", {}, ["energy-scp"]),
        # a fixed final time: foh-ptr first, cheb-scvx after it; zones do not change that
        ("rlv-max-terminal-velocity", {}, ["foh-ptr", "cheb-scvx"]),
        ("rlv-max-terminal-velocity-active-nfz", {}, ["foh-ptr", "cheb-scvx"]),
        # the same with a free final time: foh-ptr's intervals carry it, then cheb-scvx
        ("rlv-max-terminal-velocity", {"final_time": {"kind": "free"}}, ["foh-ptr", "cheb-scvx"]),
        # an optimized angle of attack: foh-ptr (alpha as a held state), cheb-scvx, hp-scp,
        # lgl-sqp
        ("shuttle-max-crossrange", {}, ["foh-ptr", "cheb-scvx", "hp-scp", "lgl-sqp"]),
        # its rate limit leaves the two that hold alpha as a state with its rate
        (
            "shuttle-max-crossrange",
            {"control_limits": {"bank_max_deg": 80, "alpha_rate_max_deg_s": 5}},
            ["foh-ptr", "hp-scp"],
        ),
        # a parabolic polar on the flat planet, waypoints: cheb-scvx
        ("cav-h-min-time-waypoints", {}, ["cheb-scvx"]),
        # a parabolic polar on the sphere: foh-ptr (normalized lift as a held state), cheb-scvx
        (
            "cav-h-min-time",
            {
                "objective": "max_terminal_velocity",
                "planet": {
                    "radius_m": 6378000,
                    "g0_m_s2": 9.81,
                    "atmosphere": {"model": "exponential", "scale_height_m": 7200},
                },
            },
            ["foh-ptr", "cheb-scvx"],
        ),
        # phases and propulsion: lgl-sqp
        ("shuttle-skip-min-propellant", {}, ["lgl-sqp"]),
    ],
)
def test_features_pick_the_methods_in_order(
    scenario: str, changes: dict[str, Any], expected: list[str]
) -> None:
    assert _candidates(_auto(scenario, **changes)) == expected


def test_a_method_is_a_candidate_exactly_when_its_own_check_accepts() -> None:
    """The rule refuses nothing a method accepts, and offers nothing it refuses."""
    for scenario in list_scenarios():
        doc = _auto(scenario.name)
        chosen = _candidates(doc)
        assert scenario.problem["method"]["name"] in chosen, scenario.name
        for name in METHODS:
            named = copy.deepcopy(scenario.problem)
            named["method"] = {"name": name}
            accepts = not check_support(ProblemDocument.model_validate(named))
            assert (name in chosen) == accepts, (scenario.name, name)


def test_a_method_that_cannot_take_autos_nodes_is_not_tried() -> None:
    selection = select(_auto("rlv-max-terminal-velocity", {"nodes": 30}))
    assert [c.name for c in selection.candidates] == ["foh-ptr"]
    assert selection.candidates[0].options.nodes == 30
    assert [i.field for i in selection.refused["cheb-scvx"]] == ["method.nodes"]
    # a method that refuses the problem anyway says so beside the nodes
    assert [i.field for i in selection.refused["hp-scp"]][:2] == [
        "method.intervals",
        "vehicle.angle_of_attack",
    ]


def test_a_held_attitude_state_gets_autos_options_on_a_fixed_final_time() -> None:
    fixed = {"final_time": {"kind": "fixed", "value_s": 2000.0}}
    free_time = {"final_time": {"kind": "free"}}
    foh = select(_auto("shuttle-max-crossrange", **fixed)).candidates[0]
    assert (foh.name, foh.options.nodes) == ("foh-ptr", 80)
    free = select(_auto("shuttle-max-crossrange")).candidates[0]
    assert (free.name, free.options.nodes) == ("foh-ptr", 80)
    heat = select(_auto("rlv-max-terminal-velocity", objective="min_heat_load", **free_time))
    assert (heat.candidates[0].name, heat.candidates[0].options.nodes) == ("foh-ptr", 120)
    scheduled = select(_auto("rlv-max-terminal-velocity")).candidates[0]
    assert scheduled.options.nodes == 40


def test_overrides_reach_the_method_they_name() -> None:
    doc = _auto("rlv-max-terminal-velocity", {"overrides": {"foh-ptr": {"max_iterations": 7}}})
    foh, cheb = select(doc).candidates
    assert (foh.name, foh.options.max_iterations) == ("foh-ptr", 7)
    assert cheb.options.max_iterations == type(cheb.options)().max_iterations


def test_a_free_final_time_gets_autos_free_time_options_under_the_callers() -> None:
    free = {"final_time": {"kind": "free"}}
    foh, cheb = select(_auto("rlv-max-terminal-velocity", **free)).candidates
    assert (foh.options.nodes, foh.options.max_iterations) == (80, 100)
    assert cheb.options.nodes == type(cheb.options)().nodes  # none of its own
    fixed = select(_auto("rlv-max-terminal-velocity")).candidates[0]
    default = type(fixed.options)()
    assert (fixed.options.nodes, fixed.options.max_iterations) == (40, default.max_iterations)
    given = {"nodes": 60, "overrides": {"foh-ptr": {"max_iterations": 50}}}
    foh = select(_auto("rlv-max-terminal-velocity", given, **free)).candidates[0]
    assert (foh.options.nodes, foh.options.max_iterations) == (60, 50)


def test_a_document_no_method_accepts_names_each_methods_reasons() -> None:
    """Fixed final time with min_control_effort: only hp-scp takes the objective, and it
    refuses a fixed final time."""
    doc = _auto(
        "rlv-min-time-hp",
        final_time={"kind": "fixed", "value_s": 1500.0},
        objective="min_control_effort",
    )
    issues = check_support(doc)
    lead, *reasons = issues
    assert (lead.field, lead.code) == ("method", "no_method_accepts")
    assert lead.message.startswith("no method accepts this problem, so auto has none to try: ")
    assert "hp-scp refuses final_time" in lead.message
    by_method = {i.message.split(" ", 1)[0].rstrip(":") for i in reasons}
    assert by_method == set(METHODS)
    hp = [i for i in reasons if i.message.startswith("hp-scp ")]
    assert [i.field for i in hp] == ["final_time"]
    assert hp[0].message.startswith("hp-scp optimizes a free final time")


def test_the_capability_matrix_reads_the_checks() -> None:
    matrix = capability_matrix()
    assert list(matrix) == list(METHODS)
    assert matrix["energy-scp"]["final_time"] == {"free": True, "fixed": False}
    assert matrix["foh-ptr"]["final_time"] == {"free": True, "fixed": True}
    assert [n for n in matrix if matrix[n]["limits"]["waypoints"]] == ["cheb-scvx"]
    assert [n for n in matrix if matrix[n]["limits"]["alpha_rate_limit"]] == ["foh-ptr", "hp-scp"]
    polar = [n for n in matrix if matrix[n]["aerodynamics"]["parabolic_polar"]]
    assert polar == ["foh-ptr", "cheb-scvx"]
    assert [n for n in matrix if matrix[n]["flight"]["phases"]] == ["lgl-sqp"]
    assert not matrix["energy-scp"]["limits"]["no_fly_zones"]
    assert matrix["foh-ptr"]["limits"]["bank_rate_limit"]
    assert all(row["atmosphere"] == {"exponential": True, "us76": True} for row in matrix.values())
    assert matrix["hp-scp"]["objectives"]["min_control_effort"]
    assert not matrix["hp-scp"]["objectives"]["min_heat_load"]


def test_the_methods_route_lists_auto_and_each_methods_matrix_row() -> None:
    listed = {m["name"]: m for m in list_methods()}
    assert list(listed) == ["auto", *METHODS]
    assert listed["auto"]["default_options"] == AutoOptions().model_dump(mode="json")
    assert listed["auto"]["features"][0].startswith("1. energy-scp: ")
    assert listed["auto"]["capabilities"]["limits"]["waypoints"] is True
    assert listed["foh-ptr"]["preference"] == 2
    assert listed["foh-ptr"]["capabilities"] == capability_matrix()["foh-ptr"]


def test_the_contract_documents_the_rule_and_the_matrix_from_their_one_source() -> None:
    text = (DOCS / "problem-contract.md").read_text(encoding="utf-8")
    assert matrix_table() in text
    for rank, (name, reason) in enumerate(PREFERENCE, 1):
        assert f"{rank}. `{name}`: {reason}" in text


def test_server_caps_read_the_options_auto_would_run() -> None:
    """A method's default over a cap is refused only when auto would run that method."""
    settings = Settings(max_iterations=500, max_time_limit_s=200.0)
    skip = _auto("shuttle-skip-min-propellant")  # lgl-sqp's default 600 iterations
    assert [(i.field, i.code) for i in cap_issues(skip, settings)] == [
        ("method.time_limit_s", "server_cap"),  # auto's default 300 s
        ("method.overrides.lgl-sqp.max_iterations", "server_cap"),
    ]
    heat = _auto("rlv-min-heat-load", {"time_limit_s": 100.0})
    assert cap_issues(heat, settings) == []


def _attempt(index: int, name: str, status: str, code: str | None = None, **result: Any) -> Attempt:
    failure = {"code": code, "message": result.pop("message", "")} if code else None
    document = {"status": status, "failure": failure, "trajectory": {}, **result}
    return Attempt(index, name, "answer", {}, document, index, 1)


def test_a_cross_check_warns_beyond_half_a_percent_and_keeps_the_better() -> None:
    objective = {"name": "max_terminal_velocity"}
    first = _attempt(1, "foh-ptr", "succeeded", objective={**objective, "value": 960.0})
    close = _attempt(2, "cheb-scvx", "succeeded", objective={**objective, "value": 962.0})
    far = _attempt(2, "cheb-scvx", "succeeded", objective={**objective, "value": 972.9})
    assert compare(first, close)["agree"] is True and compare(first, close)["warning"] is None
    entry = compare(first, far)
    assert entry["agree"] is False
    assert entry["warning"].endswith(
        "1.33 % apart: a local optimum is possible; the better verified value (cheb-scvx's) is kept"
    )
    assert better(first, far) is far  # maximized
    heat = {"name": "min_heat_load"}
    low = _attempt(1, "a", "succeeded", objective={**heat, "value": 1.0})
    high = _attempt(2, "b", "succeeded", objective={**heat, "value": 2.0})
    assert better(low, high) is low  # minimized


def test_the_most_informative_failure_and_the_message_of_none() -> None:
    budget = _attempt(
        1, "foh-ptr", "failed", "infeasible", message="not converged in 1 iterations, infeasible"
    )
    verified = _attempt(2, "cheb-scvx", "failed", "verification_failed")
    converged = _attempt(
        3, "hp-scp", "failed", "infeasible", message="start 1 of 2 (x): converged, infeasible"
    )
    precheck = _attempt(4, "lgl-sqp", "failed", "heat_limit_unreachable")
    assert most_informative([budget, verified]) is verified
    assert most_informative([budget, verified, converged]) is verified  # the earlier of equals
    assert most_informative([budget, verified, precheck]) is precheck
    verified.result["failure"]["advice"] = ["more nodes (method.nodes, now 40)"]
    failure = failure_of_none([budget, verified], verified, None, 300.0, ["hp-scp"])
    assert failure["code"] == "verification_failed"
    assert failure["message"].startswith(
        "no method succeeded (the advice is attempt 2's, whose failure says most about the "
        "problem): attempt 1, foh-ptr (history iteration 1): infeasible: not converged"
    )
    assert failure["advice"] == [
        "more nodes (method.overrides.cheb-scvx.nodes, now 40)",
        "raise method.max_attempts to try hp-scp too (they accept the problem)",
    ]
    stopped = failure_of_none([budget], budget, "timed_out", 30.0, [])
    assert stopped["code"] == "time_limit"
    assert stopped["message"].startswith("auto's time limit of 30 s for all attempts ran out; ")
    assert advice_for_auto(["raise method.time_limit_s"], "x") == ["raise method.time_limit_s"]
