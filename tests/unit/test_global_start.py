"""The global start (``initial_guess: {"kind": "global"}``) offered to every one-phase method:
its contract, what it searches (a fixed duration and a scheduled angle of attack are not
searched), the start it hands on, and a method solving from it."""

from __future__ import annotations

import copy
import time
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from app.schemas import ProblemDocument, issues_from_validation_error
from worker.solver.api import solve_problem
from worker.solver.global_search import SearchBudget
from worker.solver.methods import check_support
from worker.solver.phase_search import (
    Parameterization,
    constant_params,
    score,
    search_phases,
    start_path,
)
from worker.solver.phased_problem import build_phased_problem
from worker.solver.scenarios import get_scenario

FOH = "rlv-max-terminal-velocity"
"""A fixed final time (the duration is not searched) and an angle-of-attack schedule."""


def _doc(name: str = FOH, **guess: Any) -> dict[str, Any]:
    document: dict[str, Any] = copy.deepcopy(get_scenario(name).problem)
    document["initial_guess"] = {"kind": "global", **guess}
    return document


def _issues(document: dict[str, Any]) -> list[tuple[str, str]]:
    with pytest.raises(ValidationError) as caught:
        ProblemDocument.model_validate(document)
    return [(i.field, i.code) for i in issues_from_validation_error(caught.value)]


def test_global_kind_validates_with_and_without_search_options() -> None:
    doc = ProblemDocument.model_validate(_doc(search={"algorithm": "pso", "seed": 7}))
    assert doc.initial_guess is not None and doc.initial_guess.search is not None
    assert doc.initial_guess.search.algorithm == "pso" and doc.initial_guess.search.seed == 7
    bare = ProblemDocument.model_validate(_doc())
    assert bare.initial_guess is not None and bare.initial_guess.search is None


def test_global_kind_refuses_a_second_start_and_options_without_it() -> None:
    both = _doc(from_job="0f0e0d0c-0b0a-4909-8807-060504030201")
    assert ("initial_guess.from_job", "conflicting_start") in _issues(both)
    stray = _doc(search={"seed": 2})
    del stray["initial_guess"]["kind"]
    assert ("initial_guess.search", "search_without_global") in _issues(stray)
    nothing = _doc()
    del nothing["initial_guess"]["kind"]
    assert ("initial_guess", "missing") in _issues(nothing)
    bad_seed = _doc(search={"seed": -1})
    assert any(field == "initial_guess.search.seed" for field, _ in _issues(bad_seed))


def test_a_document_without_initial_guess_dumps_without_the_new_keys() -> None:
    document = copy.deepcopy(get_scenario(FOH).problem)
    dumped = ProblemDocument.model_validate(document).model_dump(mode="json", exclude_unset=True)
    assert "initial_guess" not in dumped


def test_methods_that_cannot_take_a_global_start_say_so() -> None:
    polar = ProblemDocument.model_validate(_doc("cav-h-min-time"))
    fields = [i.field for i in check_support(polar)]
    assert "initial_guess.kind" in fields  # a parabolic polar's lift is not searched yet
    skip = ProblemDocument.model_validate(_doc("shuttle-skip-min-propellant"))
    assert [i.field for i in check_support(skip)] == ["initial_guess"]  # its own search
    assert check_support(ProblemDocument.model_validate(_doc())) == []


def test_fixed_duration_and_scheduled_alpha_are_not_searched() -> None:
    problem = build_phased_problem(ProblemDocument.model_validate(_doc()))
    par = Parameterization(problem, 3)
    assert par.scheduled
    fixed = par.upper <= par.lower
    # three alpha knots (scheduled) and the duration (fixed final time): 4 of 7 held
    assert fixed.sum() == 4 and not fixed[3:6].any()
    outcome = search_phases(par, algorithm="ga", seed=1, population=16, budget=SearchBudget(160))
    np.testing.assert_array_equal(outcome.x[fixed], constant_params(par)[fixed])
    path = start_path(par, outcome.x)
    assert path.alpha is None  # the schedule's, not a searched one
    # the start lasts the fixed final time exactly (nondimensional, rounding only)
    assert problem.phases[0].duration_min == pytest.approx(path.t[-1], rel=1e-12)
    assert path.y.shape == (path.t.size, 6) and np.isfinite(path.y).all()


def test_the_search_lowers_the_terminal_misses_of_constant_controls() -> None:
    problem = build_phased_problem(ProblemDocument.model_validate(_doc()))
    par = Parameterization(problem, 3)
    outcome = search_phases(par, algorithm="pso", seed=3, population=16, budget=SearchBudget(320))
    constant = float(score(par, constant_params(par)[None, :])[0])
    # a search that did not beat wings-level flight would hand on nothing better than a guess
    assert outcome.score < 0.5 * constant


@pytest.mark.slow
def test_a_method_solves_from_the_global_start_and_says_where_it_started() -> None:
    document = _doc(search={"seed": 1, "max_evaluations": 800})
    result = solve_problem(ProblemDocument.model_validate(document))
    assert result["status"] == "succeeded", result.get("failure")
    note = result["provenance"]["initial_guess"]
    assert note.startswith("global search (ga, seed 1)") and "800 flights" in note
    assert result["verification"]["feasible"]


def test_a_global_start_stopped_by_the_caller_ends_cancelled() -> None:
    result = solve_problem(ProblemDocument.model_validate(_doc()), should_stop=lambda: True)
    assert result["status"] == "cancelled"
    assert "global search" in result["failure"]["message"]


@pytest.mark.slow
def test_a_search_asking_for_more_than_its_job_stops_at_half_the_jobs_limit() -> None:
    """A search's own time limit (here an hour) is cut to half the job's (10 s): the method gets
    the rest and the job ends with a flown, verified trajectory instead of being killed at its
    limit with nothing. Stopped from outside after 60 s so that a search that is not cut fails
    the test instead of running for an hour."""
    document = _doc(search={"seed": 1, "max_evaluations": 1_000_000, "time_limit_s": 3600})
    document["method"]["time_limit_s"] = 10
    begun = time.monotonic()
    result = solve_problem(
        ProblemDocument.model_validate(document),
        should_stop=lambda: time.monotonic() - begun > 60,
    )
    assert result["status"] in ("succeeded", "timed_out"), result.get("failure")
    note = result["provenance"]["initial_guess"]
    assert "cut to 5 s" in note, note
    assert result["trajectory"]["time_s"] and result["verification"] is not None
    # the method ran on what the search left (the search may pass its 5 s by one generation)
    assert result["timing"]["wall_s"] < 7.5  # not the 10 s of the whole job
