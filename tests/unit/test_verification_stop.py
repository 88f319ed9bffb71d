"""A stop asked for during the verification ends it within a poll interval, as ``cancelled``.

A real solve of the built-in paper 000 scenario (its verification takes seconds at 121 nodes);
the stop check turns true once the verification phase has begun.
"""

from __future__ import annotations

import time

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
