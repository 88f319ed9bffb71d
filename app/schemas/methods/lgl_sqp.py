"""Options of paper 004's evolutionary collocation: a global initial guess by a genetic algorithm
or particle swarm, then Legendre–Gauss–Lobatto collocation of all phases solved by SQP
(``lgl-sqp``)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from app.schemas.base import FieldProblem, raise_problems
from app.schemas.guess import GlobalGuessOptions
from app.schemas.methods.common import ScpRunOptions


class LglSqpOptions(ScpRunOptions):
    """Paper 004's method: LGL collocation in integral form on segments of every phase, linked
    by state continuity, solved by SQP (a Clarabel QP per iteration, the convexified exact
    Lagrangian Hessian, an l1 merit line search or paper 003's filter)."""

    name: Literal["lgl-sqp"] = Field("lgl-sqp", description="Method name.")
    nodes: int = Field(
        81,
        ge=3,
        le=2001,
        description="Points of each phase: segments x degree + 1 (default 20 segments of "
        "degree 4), so at least degree + 1 (one segment); 3 (one segment of degree 2, or two "
        "of degree 1) is the fewest the method runs with.",
    )
    degree: int = Field(4, ge=1, le=12, description="LGL degree of every segment.")
    phase_nodes: list[int] | None = Field(
        None,
        description="Points of each phase in order, overriding nodes (each minus 1 a multiple "
        "of degree).",
    )
    refine_burns: bool = Field(
        True,
        description="Once converged, solve each phase that may thrust again from that answer "
        "on twice its segments, a segment holding a burn's start or end on eight (not with "
        "phase_nodes): paper 004's exit altitude after propagation 276 m off on 20 segments, "
        "25 m after the refinement.",
    )
    refine_path_limits: bool = Field(
        True,
        description="Once converged, halve each segment whose interpolated states exceed a "
        "path limit by more than 0.2 % between its points and solve again from that answer, "
        "up to three rounds (not with phase_nodes): the limits are met at the points, and the "
        "flight between them is what the verification judges.",
    )
    max_iterations: int = Field(
        600,
        ge=1,
        le=2000,
        description="Most SQP iterations (paper 004's case from a GA/PSO guess: 100-250).",
    )
    time_limit_s: float = Field(
        900.0,
        gt=0,
        le=3600,
        description="CPU-time limit of the solve, s of the solving process's CPU time (all its "
        "threads); a wall-clock safety limit of 4 x as many seconds also ends it.",
    )
    initial_guess: Literal["global", "constant"] = Field(
        "global",
        description="global: the GA/PSO search of global_guess; constant: each phase flown with "
        "constant mid-range controls for the middle of its duration bounds.",
    )
    global_guess: GlobalGuessOptions = Field(
        default_factory=GlobalGuessOptions, description="The global search's settings."
    )
    line_search: Literal["merit", "filter"] = Field(
        "merit",
        description="merit: Armijo on the l1 exact penalty of the elastic QP; filter: paper "
        "003's non-monotone filter on (violation, objective).",
    )
    feasibility_tolerance: float = Field(
        1e-8,
        gt=0,
        le=1e-2,
        description="Largest scaled constraint violation of a converged answer (defects in "
        "state scales: 1e-8 of the altitude scale is 1.3 mm).",
    )
    step_tolerance: float = Field(
        1e-6, gt=0, le=1e-1, description="Largest scaled step of a converged answer."
    )

    @model_validator(mode="after")
    def _meshes(self) -> LglSqpOptions:
        counts = self.phase_nodes if self.phase_nodes is not None else [self.nodes]
        problems = [
            FieldProblem(
                ("phase_nodes", i) if self.phase_nodes is not None else ("nodes",),
                "mesh_shape",
                f"{n} points do not make whole segments of degree {self.degree} "
                f"(points - 1 must be a multiple of {self.degree}, and at least "
                f"{max(3, self.degree + 1)} points)",
                n,
            )
            for i, n in enumerate(counts)
            if n < 3 or (n - 1) % self.degree
        ]
        raise_problems("LglSqpOptions", problems)
        return self
