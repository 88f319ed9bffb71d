"""Backend-neutral result type and the backend protocol (the factory by name is ``registry``).

The SCP loop talks only to ``ConicBackend``, so the conic solver is a configuration choice.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from worker.solver.conic.problem import ConeProblem
from worker.solver.conic.status import ConicStatus

CVXPY_SOLVERS: tuple[str, ...] = ("CLARABEL", "ECOS", "SCS")
"""Solvers reachable through cvxpy that handle second-order cones."""


@dataclass
class ConicSolution:
    """Result of one conic solve: the point (if usable), the mapped status and the time spent.

    ``solve_time_s`` is the solver's own time; ``setup_time_s`` is the rest of the time spent in the
    backend (building/updating the solver, or cvxpy's compilation). ``solver`` names who answered.
    """

    x: NDArray[np.float64] | None
    status: ConicStatus
    raw_status: str
    objective: float | None
    solve_time_s: float
    iterations: int
    setup_time_s: float
    solver: str
    clarabel_setup_s: float = 0.0
    """Time inside Clarabel's own constructor or ``update()`` (its setup work) for this solve."""
    y: NDArray[np.float64] | None = None
    """Multipliers of the rows of A x + s = b in Clarabel's sign (P x + q + A'y = 0), when the
    backend reports them for every row; the SQP step of the time-domain SCP needs them."""


@runtime_checkable
class ConicBackend(Protocol):
    """Anything that solves a ConeProblem and reports a ConicSolution."""

    name: str

    def solve(self, problem: ConeProblem, *, time_limit_s: float | None = None) -> ConicSolution:
        """Solve ``problem``, stopping after about ``time_limit_s`` s of solver time if set."""
        ...
