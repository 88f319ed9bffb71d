"""Which answers auto cross-checks by default: the classes known to have several local optima,
and heat loads whose answer skips."""

from __future__ import annotations

from typing import Any

import numpy as np

from app.schemas import AutoOptions, ProblemDocument

RANGE_OBJECTIVES = frozenset(
    {"max_final_latitude", "min_final_latitude", "max_final_longitude", "min_final_longitude"}
)
"""Objectives on where the flight ends: the turn direction and the bank-sign choices along the
way give separate local optima (Betts' Shuttle from a 60 deg heading: cheb-scvx once converged
to a verified 62.40 deg of final latitude, lgl-sqp and the NLP reference to 63.906 deg;
docs/problem-contract.md)."""
SKIP_OBJECTIVES = frozenset({"min_heat_load"})
"""Objectives whose answers may skip, each skip's depth a choice between separate local optima
(the user-problem suite's RLV heat load 015 has a shallow-skip and a deep-skip optimum,
docs/problem-contract.md)."""
SKIP_CLIMB_M = 7200.0
"""A climb of more than this from a low point is a skip: one scale height of Earth's
atmosphere, over which the density falls by a factor e (paper 000's heat-load optimum
undulates by 4 km, the suite's 015 climbs 16 km)."""


def skips(result: dict[str, Any]) -> bool:
    """Whether the result's trajectory climbs by more than ``SKIP_CLIMB_M`` from a low point."""
    altitude = (result.get("trajectory") or {}).get("altitude_m")
    if not altitude:
        return False
    h = np.asarray(altitude, dtype=float)
    climb = h - np.minimum.accumulate(h)
    return bool(np.nanmax(climb) > SKIP_CLIMB_M)


def cross_check_wanted(problem: ProblemDocument, answer: dict[str, Any] | None = None) -> bool:
    """Whether auto runs a cross-check after the success ``answer``: as ``method.cross_check``
    says, or, left null, for the objectives of :data:`RANGE_OBJECTIVES`, and for those of
    :data:`SKIP_OBJECTIVES` when the answer skips."""
    auto = problem.method
    assert isinstance(auto, AutoOptions)
    if auto.cross_check is not None:
        return auto.cross_check
    names = problem.objective.names()
    if not RANGE_OBJECTIVES.isdisjoint(names):
        return True
    return answer is not None and not SKIP_OBJECTIVES.isdisjoint(names) and skips(answer)
