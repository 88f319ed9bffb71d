"""A start for any one-phase method from a global search (``initial_guess: {"kind": "global"}``):
paper 004's GA/PSO search of a few control parameters (``phase_search``), scored by the
propagated terminal misses and path-limit excess, its best flight handed to the method as a
start trajectory, as a user's earlier answer would be (``problem.guess``).

For a problem far from a method's own guess (another terminal point, a heading change, a long
or short flight) the search finds controls that fly there; the method interpolates the flight
onto its own grid (in time or in energy) and optimizes from it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from app.schemas import ProblemDocument
from app.schemas.guess import GlobalGuessOptions
from worker.solver.global_search import SearchBudget, SearchOutcome, clamp_note, search_seconds
from worker.solver.phase_search import Parameterization, search_phases, start_path
from worker.solver.phased_problem import build_phased_problem
from worker.solver.problem import EntryProblem


class GlobalStartStoppedError(Exception):
    """The caller asked to stop during the search."""


def with_global_start(
    doc: ProblemDocument,
    problem: EntryProblem,
    *,
    should_stop: Callable[[], bool] | None = None,
    job_time_limit_s: float,
) -> tuple[EntryProblem, str]:
    """``problem`` with the global search's best flight as its start, and a line saying how it
    was found (for the result's provenance). The search takes at most its share of the job's
    time limit (``global_search.search_seconds``), whatever its own asks."""
    assert doc.initial_guess is not None
    options = doc.initial_guess.search or GlobalGuessOptions()
    phased = build_phased_problem(doc)
    par = Parameterization(phased, options.knots)

    def progress(_generation: int, _best: float) -> None:
        if should_stop is not None and should_stop():
            raise GlobalStartStoppedError

    outcome = search_phases(
        par,
        algorithm=options.algorithm,
        seed=options.seed,
        population=options.population,
        budget=SearchBudget(
            options.max_evaluations, search_seconds(options.time_limit_s, job_time_limit_s)
        ),
        progress=progress,
    )
    path = start_path(par, outcome.x)
    note = describe(outcome, path.t[-1], problem) + clamp_note(
        options.time_limit_s, job_time_limit_s
    )
    return dataclasses.replace(problem, guess=path), note


def describe(outcome: SearchOutcome, duration: float, problem: EntryProblem) -> str:
    """How the start was found, in a line."""
    return (
        f"global search ({outcome.algorithm}, seed {outcome.seed}): {outcome.generations} "
        f"generations, {outcome.evaluations} flights in {outcome.wall_s:.1f} s, stopped by "
        f"{outcome.stopped_by}; best score {outcome.score:.4g} (terminal misses in 1 km, 1 deg, "
        f"100 m/s units, path excess x10); its flight {duration * problem.scales.time_s:.1f} s"
    )
