"""The conic backend registry: every backend name the options accept, and the factory by name.

It sits above the backends (they import only ``base``), so the backend modules and the
protocol they implement form no import cycle.
"""

from __future__ import annotations

from worker.solver.conic.base import CVXPY_SOLVERS, ConicBackend
from worker.solver.conic.clarabel_direct import ClarabelBackend
from worker.solver.conic.cvxpy_backend import CvxpyBackend
from worker.solver.conic.fallback import FallbackBackend
from worker.solver.conic.piqp_direct import PiqpBackend

KNOWN_BACKENDS: tuple[str, ...] = (
    "clarabel",
    "piqp",
    "cvxpy",
    *(f"cvxpy:{solver}" for solver in CVXPY_SOLVERS),
)
"""Every name ``make_backend`` accepts (``cvxpy`` alone means ``cvxpy:CLARABEL``)."""


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
    return FallbackBackend(primary, _make_single(fallback_name))


def _make_single(name: str) -> ConicBackend:
    """Build one unwrapped backend by name, raising ValueError listing the known names."""
    if name == "clarabel":
        return ClarabelBackend()
    if name == "piqp":
        return PiqpBackend()
    solver = _cvxpy_solver_of(name)
    if solver is not None:
        return CvxpyBackend(solver=solver)
    raise ValueError(f"unknown conic backend {name!r}; known: {', '.join(KNOWN_BACKENDS)}")
