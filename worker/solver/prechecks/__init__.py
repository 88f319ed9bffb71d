"""Cheap physical pre-checks of a problem: what makes it infeasible, or the likely cause of a
failed solve, with the figure that shows it.

``proven_infeasible`` runs before the method (tens of milliseconds: one flight to the end of the
first pull-up) and returns only what proves that no solution exists: a path limit below the
first-pull-up peak of the least-bank flight, where that bound is sound (``limits``). The solve
then ends at once, failed with code ``infeasible``, the figure and what to change.
``likely_causes`` runs after a solve failed (a fraction of a second: families of constant-bank
flights, ``reach``) and names what likely made it fail: a limit the least-bank flight exceeds, a
target out of reach, a zone across the corridor, a fixed final time far from what the flight
takes. Zones that hold the entry point or a target are refused by the problem contract itself.

Flat-planet problems (paper 001's model, map coordinates) are not checked.
"""

from __future__ import annotations

from worker.solver.prechecks.finding import Finding
from worker.solver.prechecks.limits import limit_findings
from worker.solver.prechecks.pull_up import PullUp, least_bank_pull_up
from worker.solver.prechecks.reach import reach_findings
from worker.solver.problem import EntryProblem

__all__ = ["Finding", "PullUp", "checked", "likely_causes", "proven_infeasible"]


def checked(problem: EntryProblem) -> bool:
    """Whether the pre-checks apply: a flight over the spherical planet."""
    return problem.planet_model == "spherical"


def proven_infeasible(problem: EntryProblem) -> tuple[list[Finding], PullUp | None]:
    """What proves ``problem`` infeasible before any method runs, and the least-bank flight's
    pull-up when it was flown (None where no proof is possible: an attitude held by the
    optimizer, a flat planet)."""
    if not checked(problem) or problem.alpha_optimized or problem.lift_range is not None:
        return [], None
    pull_up = least_bank_pull_up(problem)
    return [f for f in limit_findings(problem, pull_up) if f.proven], pull_up


def likely_causes(problem: EntryProblem, pull_up: PullUp | None = None) -> list[Finding]:
    """What likely made a solve of ``problem`` fail, most specific first."""
    if not checked(problem):
        return []
    pull_up = pull_up or least_bank_pull_up(problem)
    return [*limit_findings(problem, pull_up), *reach_findings(problem)]
