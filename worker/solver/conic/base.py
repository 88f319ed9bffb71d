"""Backend-neutral result type, the backend protocol, and the factory that builds a backend by name.

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

KNOWN_BACKENDS: tuple[str, ...] = (
    "clarabel",
    "cvxpy",
    *(f"cvxpy:{solver}" for solver in CVXPY_SOLVERS),
)
"""Every name ``make_backend`` accepts (``cvxpy`` alone means ``cvxpy:CLARABEL``)."""


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


def _cvxpy_solver_of(name: str) -> str | None:
    """Return the cvxpy solver a backend name selects, or None if it is not a cvxpy name."""
    if name == "cvxpy":
        return "CLARABEL"
    if name.startswith("cvxpy:"):
        solver = name.split(":", 1)[1].upper()
        return solver if solver in CVXPY_SOLVERS else None
    return None


def make_backend(name: str, *, fallback: str | None = None) -> ConicBackend:
    """Build the backend called ``name``; with ``fallback`` (a cvxpy solver such as "ECOS"), wrap it
    so NUMERICAL_ERROR or INACCURATE answers are re-solved by ``cvxpy:<fallback>``."""
    primary = _make_single(name)
    if fallback is None:
        return primary
    fallback_name = fallback if fallback.startswith("cvxpy") else f"cvxpy:{fallback}"
    from worker.solver.conic.fallback import FallbackBackend

    return FallbackBackend(primary, _make_single(fallback_name))


def _make_single(name: str) -> ConicBackend:
    """Build one unwrapped backend by name, raising ValueError listing the known names."""
    if name == "clarabel":
        from worker.solver.conic.clarabel_direct import ClarabelBackend

        return ClarabelBackend()
    solver = _cvxpy_solver_of(name)
    if solver is not None:
        from worker.solver.conic.cvxpy_backend import CvxpyBackend

        return CvxpyBackend(solver=solver)
    raise ValueError(f"unknown conic backend {name!r}; known: {', '.join(KNOWN_BACKENDS)}")
