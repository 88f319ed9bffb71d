"""Which problems auto cross-checks by default: the classes known to have several local optima."""

from __future__ import annotations

from app.schemas import AutoOptions, ProblemDocument

RANGE_OBJECTIVES = frozenset(
    {"max_final_latitude", "min_final_latitude", "max_final_longitude", "min_final_longitude"}
)
"""Objectives on where the flight ends: the turn direction and the bank-sign choices along the
way give separate local optima (Betts' Shuttle from a 60 deg heading: cheb-scvx converges to a
verified 62.40 deg of final latitude, lgl-sqp and the NLP reference to 63.906 deg)."""


def cross_check_wanted(problem: ProblemDocument) -> bool:
    """Whether auto runs a cross-check after a success: as ``method.cross_check`` says, or, left
    null, for the objectives of :data:`RANGE_OBJECTIVES`."""
    auto = problem.method
    assert isinstance(auto, AutoOptions)
    if auto.cross_check is not None:
        return auto.cross_check
    return not RANGE_OBJECTIVES.isdisjoint(problem.objective.names())
