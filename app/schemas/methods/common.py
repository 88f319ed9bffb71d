"""Options every method shares: bounded magnitudes, the SCP budgets and the conic solver."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from app.schemas import bounds
from app.schemas.base import FieldProblem, StrictModel, raise_problems
from app.schemas.limits import MAX_ITERATIONS, MAX_NODES, MAX_TIME_LIMIT_S

ConicBackendName = Literal["clarabel", "piqp", "cvxpy"]
"""The subproblem solvers a method's options may name (``worker.solver.conic.registry``)."""


class BoundedOptions(StrictModel):
    """Options whose every number is at most ``bounds.WEIGHT_MAX`` in magnitude (the models
    bound each number from below themselves; this keeps absurd magnitudes from the solver)."""

    @model_validator(mode="after")
    def _magnitudes(self) -> BoundedOptions:
        problems = [
            FieldProblem(
                (name,),
                "magnitude_limit",
                f"{value:g} exceeds the largest magnitude {bounds.WEIGHT_MAX:g} a method option "
                "may have",
                value,
            )
            for name, value in self
            if isinstance(value, float) and abs(value) > bounds.WEIGHT_MAX
        ]
        raise_problems(type(self).__name__, problems)
        return self


class ScpRunOptions(BoundedOptions):
    """Options every SCP method shares: its name and node count (each method declares its own
    literal name and default), iteration and time budgets, the conic solver."""

    name: str = Field(..., description="Method name.")
    nodes: int = Field(
        40,
        ge=3,
        le=MAX_NODES,
        description=f"Discretization nodes (N + 1 for N intervals), 3..{MAX_NODES}.",
    )

    max_iterations: int = Field(
        30, ge=1, le=MAX_ITERATIONS, description=f"Most SCP iterations, 1..{MAX_ITERATIONS}."
    )
    time_limit_s: float = Field(
        120.0,
        gt=0,
        le=MAX_TIME_LIMIT_S,
        description="CPU-time limit of the solve, s of the solving process's CPU time (all its "
        "threads: the answer does not depend on other processes' load), in "
        f"(0, {MAX_TIME_LIMIT_S:g}]; a wall-clock safety limit of 4 x as many seconds also ends "
        "it.",
    )
    second_start: bool | None = Field(
        None,
        description="After a success, run the method again from another start (the global "
        "search's, initial_guess kind global; lgl-sqp its own search's next seed) and keep the "
        "better verified answer, both values in the result's cross_check and both runs in its "
        "attempts; the second run has what the first left of time_limit_s. null: where the "
        "problem class has separate local optima (a minimum heat load whose answer skips: "
        "climbs more than 7.2 km from a low point); true: after every success; false: never. "
        "Not when the document gives its own initial_guess. Under method auto its own "
        "cross-check does this.",
    )
    conic_backend: ConicBackendName = Field(
        "clarabel",
        description='Subproblem solver: "clarabel" directly; "piqp" for the subproblems that are '
        "quadratic programs (PIQP, with Clarabel for any second-order cone and for whatever "
        'PIQP does not solve); or "cvxpy" (Clarabel through cvxpy).',
    )
    fallback_solver: Literal["ECOS", "SCS"] | None = Field(
        None,
        description="cvxpy solver tried when the primary one fails on a subproblem; none = no "
        "fallback.",
    )
    conic_time_limit_s: float | None = Field(
        None,
        gt=0,
        le=MAX_TIME_LIMIT_S,
        description="Wall-clock limit of each convex subproblem, s; none = only the overall "
        "limits.",
    )
