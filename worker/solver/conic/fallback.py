"""Backend wrapper that re-solves with a second backend when the first reports numerical trouble.

Interior-point solvers occasionally stall on badly scaled SCP subproblems; a second solver with a
different algorithm or linear algebra often still answers.
"""

from __future__ import annotations

from dataclasses import replace
from time import perf_counter

from worker.solver.conic.base import ConicBackend, ConicSolution
from worker.solver.conic.problem import ConeProblem
from worker.solver.conic.status import ConicStatus

RETRY_STATUSES: frozenset[ConicStatus] = frozenset(
    {ConicStatus.NUMERICAL_ERROR, ConicStatus.INACCURATE}
)
"""Primary statuses that trigger a re-solve by the fallback backend."""

_RANK: dict[ConicStatus, int] = {
    ConicStatus.OPTIMAL: 3,
    ConicStatus.INACCURATE: 2,
    ConicStatus.INFEASIBLE: 1,
    ConicStatus.TIME_LIMIT: 1,
    ConicStatus.NUMERICAL_ERROR: 0,
}


def pick_better(first: ConicSolution, second: ConicSolution) -> ConicSolution:
    """Return ``second`` only if its status is strictly more informative than ``first``'s."""
    return second if _RANK[second.status] > _RANK[first.status] else first


class FallbackBackend:
    """Solve with ``primary``; on NUMERICAL_ERROR or INACCURATE re-solve with ``fallback``.

    The returned solution is the better of the two (``solver`` says which one produced it); its
    times are the sums over both attempts, so time accounting stays honest.
    """

    def __init__(self, primary: ConicBackend, fallback: ConicBackend) -> None:
        """Wrap ``primary`` with ``fallback`` as the second opinion."""
        self.primary = primary
        self.fallback = fallback
        self.name = f"{primary.name}>{fallback.name}"

    def solve(self, problem: ConeProblem, *, time_limit_s: float | None = None) -> ConicSolution:
        """Solve with the primary, and with the fallback on trouble while time remains."""
        start = perf_counter()
        first = self.primary.solve(problem, time_limit_s=time_limit_s)
        if first.status not in RETRY_STATUSES:
            return first
        remaining: float | None = None
        if time_limit_s is not None:
            remaining = time_limit_s - (perf_counter() - start)
            if remaining <= 0.0:
                return first
        second = self.fallback.solve(problem, time_limit_s=remaining)
        chosen = pick_better(first, second)
        return replace(
            chosen,
            solve_time_s=first.solve_time_s + second.solve_time_s,
            setup_time_s=first.setup_time_s + second.setup_time_s,
        )
