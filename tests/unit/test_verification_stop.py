"""A stop asked for during the verification ends it within a poll interval, as ``cancelled``;
one asked for during the optimization ends it there, says before which iteration, and starts no
verification.

Real solves of built-in scenarios (paper 000's verification takes seconds at 121 nodes); the
stop check turns true once the verification phase has begun, or after a given iteration.
"""

from __future__ import annotations

import time
from typing import Any

import pytest

from app.schemas import ProblemDocument
from worker.solver.api import solve_problem
from worker.solver.scenarios import get_scenario
from worker.solver.verification import STOP_POLL_INTERVAL_S

pytestmark = pytest.mark.slow


def test_a_stop_during_the_verification_cancels_it_and_keeps_the_history() -> None:
    problem = ProblemDocument.model_validate(get_scenario("rlv-min-heat-load").problem)
    phases: list[str] = []
    asked_after_verifying = 0

    def should_stop() -> bool:
        nonlocal asked_after_verifying
        if phases[-1] != "verifying":
            return False
        asked_after_verifying += 1
        return True

    start = time.perf_counter()
    result = solve_problem(problem, should_stop=should_stop, on_phase=phases.append)
    assert phases == ["optimizing", "verifying"]
    assert result["status"] == "cancelled"
    assert result["failure"]["code"] == "cancelled"
    assert "during the verification" in result["failure"]["message"]
    assert result["verification"] is None
    assert result["history"] and result["trajectory"]
    assert asked_after_verifying == 1  # the first poll of the propagation stopped it
    # one poll interval of propagation at most, against seconds for the whole verification
    # (tolerance: the interval plus scheduling noise on a shared machine)
    assert result["timing"]["verification_s"] < STOP_POLL_INTERVAL_S + 0.5
    assert time.perf_counter() - start < 30.0


def test_without_a_stop_the_verification_runs_to_its_report() -> None:
    problem = ProblemDocument.model_validate(get_scenario("rlv-min-heat-load").problem)
    result = solve_problem(problem, should_stop=lambda: False)
    assert result["status"] == "succeeded"
    assert result["verification"]["feasible"] is True


STOPPED_AT = 2
"""Iterations complete when the stop check of the optimization tests turns true."""


@pytest.mark.parametrize(
    ("scenario", "method"),
    [
        ("rlv-min-heat-load", {"nodes": 41}),
        ("rlv-max-terminal-velocity", {}),  # foh-ptr: the first of its two starts
        ("rlv-min-time-hp", {}),
        ("shuttle-skip-min-propellant", {"initial_guess": "constant", "nodes": 21}),
    ],
)
def test_a_stop_during_the_optimization_says_before_which_iteration(
    scenario: str, method: dict[str, Any]
) -> None:
    raw = dict(get_scenario(scenario).problem)
    raw["method"] = {**raw["method"], **method}
    problem = ProblemDocument.model_validate(raw)
    phases: list[str] = []
    records: list[dict[str, Any]] = []
    result = solve_problem(
        problem,
        on_iteration=records.append,
        should_stop=lambda: len(records) >= STOPPED_AT,
        on_phase=phases.append,
    )
    assert phases == ["optimizing"]  # no verification was started
    assert (result["status"], result["failure"]["code"]) == ("cancelled", "cancelled")
    assert result["failure"]["message"] == (
        f"stopped during the optimization, before iteration {STOPPED_AT + 1}; the trajectory "
        "is the last iterate and was not verified"
    )
    assert result["verification"] is None and result["trajectory"]
    assert len(result["history"]) == result["timing"]["iterations"] == STOPPED_AT


def test_a_stop_in_a_later_start_reports_the_stop() -> None:
    """foh-ptr's second start stopped after its first iteration, the first start having used
    its budget: the run reports the stop (not the first start's failure), in the history's
    numbering."""
    raw = dict(get_scenario("rlv-max-terminal-velocity").problem)
    raw["method"] = {**raw["method"], "max_iterations": 3}
    records: list[dict[str, Any]] = []
    result = solve_problem(
        ProblemDocument.model_validate(raw),
        on_iteration=records.append,
        should_stop=lambda: len(records) >= 4,
    )
    assert [(s["start"], s["status"], s["iterations"], s["chosen"]) for s in result["starts"]] == [
        (1, "max_iterations", 3, False),
        (2, "cancelled", 1, True),
    ]
    assert (result["status"], result["failure"]["code"]) == ("cancelled", "cancelled")
    assert result["failure"]["message"].startswith(
        "stopped during the optimization, before iteration 5;"
    )
    assert result["verification"] is None and len(result["history"]) == 4
