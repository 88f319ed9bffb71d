"""Solver-independent status of one conic solve, and the maps from each backend's own statuses.

The SCP loop reacts to five outcomes only; every backend status is folded into one of them.
"""

from __future__ import annotations

from enum import StrEnum


class ConicStatus(StrEnum):
    """Outcome of one conic subproblem solve, as the SCP loop needs to see it."""

    OPTIMAL = "optimal"
    INACCURATE = "inaccurate"
    INFEASIBLE = "infeasible"
    NUMERICAL_ERROR = "numerical_error"
    TIME_LIMIT = "time_limit"

    @property
    def usable(self) -> bool:
        """True when the solve returned a point the SCP may accept (optimal or inaccurate)."""
        return self in (ConicStatus.OPTIMAL, ConicStatus.INACCURATE)


# "Infeasible" here means "no finite optimum exists": primal infeasibility and dual
# infeasibility (an unbounded subproblem) both leave the SCP without a usable step.
# An interior-point method that runs out of iterations is stalling, so MaxIterations is
# treated as numerical trouble (which a fallback solver may cure), not as a time limit.
_CLARABEL_MAP: dict[str, ConicStatus] = {
    "Solved": ConicStatus.OPTIMAL,
    "AlmostSolved": ConicStatus.INACCURATE,
    "PrimalInfeasible": ConicStatus.INFEASIBLE,
    "DualInfeasible": ConicStatus.INFEASIBLE,
    "AlmostPrimalInfeasible": ConicStatus.INFEASIBLE,
    "AlmostDualInfeasible": ConicStatus.INFEASIBLE,
    "MaxIterations": ConicStatus.NUMERICAL_ERROR,
    "MaxTime": ConicStatus.TIME_LIMIT,
    "NumericalError": ConicStatus.NUMERICAL_ERROR,
    "InsufficientProgress": ConicStatus.NUMERICAL_ERROR,
    "Unsolved": ConicStatus.NUMERICAL_ERROR,
    "CallbackTerminated": ConicStatus.TIME_LIMIT,
}

# cvxpy folds "max iterations" and "max time" into ``user_limit``; the cvxpy backend
# narrows it to NUMERICAL_ERROR when no time limit was requested.
_CVXPY_MAP: dict[str, ConicStatus] = {
    "optimal": ConicStatus.OPTIMAL,
    "optimal_inaccurate": ConicStatus.INACCURATE,
    "infeasible": ConicStatus.INFEASIBLE,
    "infeasible_inaccurate": ConicStatus.INFEASIBLE,
    "unbounded": ConicStatus.INFEASIBLE,
    "unbounded_inaccurate": ConicStatus.INFEASIBLE,
    "infeasible_or_unbounded": ConicStatus.INFEASIBLE,
    "user_limit": ConicStatus.TIME_LIMIT,
    "solver_error": ConicStatus.NUMERICAL_ERROR,
}


def clarabel_status_name(status: object) -> str:
    """Return the bare name of a Clarabel status ("Solved"), whatever object form it has."""
    text = str(status)
    return text.rsplit(".", 1)[-1]


def map_clarabel_status(status: object) -> ConicStatus:
    """Map a Clarabel ``SolverStatus`` (or its name) to ConicStatus; unknown -> NUMERICAL_ERROR."""
    return _CLARABEL_MAP.get(clarabel_status_name(status), ConicStatus.NUMERICAL_ERROR)


def map_cvxpy_status(status: str | None) -> ConicStatus:
    """Map a cvxpy problem status string to a ConicStatus; unknown or None -> NUMERICAL_ERROR."""
    if status is None:
        return ConicStatus.NUMERICAL_ERROR
    return _CVXPY_MAP.get(status, ConicStatus.NUMERICAL_ERROR)
