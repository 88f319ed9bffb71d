"""Options of the hp-adaptive pseudospectral SCP with angle of attack and bank as states (paper
003, ``hp-scp``)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from app.schemas.base import FieldProblem, raise_problems
from app.schemas.methods.common import BoundedOptions, ScpRunOptions


class HpStopTolerance(BoundedOptions):
    """Convergence test: every point moves less than these between iterations (paper 003 sec. 5,
    its epsilon: 100 m, 1 m/s, 0.1 deg for every angle) and the final time by less than
    ``final_time_s``, or the objective has settled (``relative_cost``)."""

    altitude_m: float = Field(100.0, gt=0, description="Altitude change tolerance, m.")
    longitude_deg: float = Field(0.1, gt=0, description="Longitude change tolerance, deg.")
    latitude_deg: float = Field(0.1, gt=0, description="Latitude change tolerance, deg.")
    velocity_m_s: float = Field(1.0, gt=0, description="Speed change tolerance, m/s.")
    flight_path_angle_deg: float = Field(
        0.1, gt=0, description="Flight path angle change tolerance, deg."
    )
    heading_deg: float = Field(0.1, gt=0, description="Heading change tolerance, deg.")
    bank_deg: float = Field(0.1, gt=0, description="Bank angle change tolerance, deg.")
    angle_of_attack_deg: float = Field(
        0.1, gt=0, description="Angle of attack change tolerance, deg."
    )
    final_time_s: float = Field(0.1, gt=0, description="Final time change tolerance, s.")
    relative_cost: float = Field(
        1.0e-4,
        gt=0,
        lt=1,
        description="A run whose objective moved by less than this share over the last "
        "settle_iterations accepted steps is also converged (with its defects within "
        "tolerance and the trust weight at its floor).",
    )
    settle_iterations: int = Field(
        5, ge=2, le=100, description="Accepted steps the relative_cost test looks back over."
    )


class HpScpOptions(ScpRunOptions):
    """Paper 003's SCP on a multi-interval Chebyshev-Gauss-Lobatto mesh with free final time."""

    name: Literal["hp-scp"] = Field("hp-scp", description="Method name.")
    nodes: int = Field(
        101,
        ge=3,
        le=2000,
        description="Points of the initial mesh: intervals x degree + 1 (default 20 intervals "
        "of degree 5; paper 003 starts from 10 intervals of 8 points), so at least intervals "
        "+ 1 (degree 1); 3 (one interval of degree 2) is the fewest the method iterates with "
        "(with 2 its first step leaves the physical range).",
    )
    intervals: int = Field(
        20, ge=1, le=400, description="Intervals of the initial mesh; nodes - 1 must divide."
    )
    max_iterations: int = Field(
        250,
        ge=1,
        le=500,
        description="Most SCP iterations, 1..500 (paper 003's case: 40; the user-problem suite's "
        "maximum final latitudes: up to 200).",
    )
    initial_alpha_deg: float = Field(
        20.0, gt=-90, lt=90, description="Angle of attack of the constant-control guess, deg."
    )
    initial_bank_deg: float | None = Field(
        None,
        ge=-90,
        le=90,
        description="Bank angle of the constant-control guess, deg, within the bank range; none "
        "= 3/8 of the range's half-width above its middle (30 deg for [-80, 80]).",
    )
    final_time_guess_s: float | None = Field(
        None,
        gt=0,
        le=100_000,
        description="Flight time of the guess, s; none = the constant-control flight down to the "
        "terminal altitude (or speed).",
    )
    guess: Literal["propagated", "linear"] = Field(
        "linear",
        description="Initial reference: each state with a terminal target straight from its "
        "initial value to the target over the guessed flight time (the constant-control "
        "flight's), the other states and the attitude as that flight flies them; or the "
        "constant-control flight itself (paper 003's stage 1, which its own case pins). The "
        "constant-control flight can pass the target high and fast, a start the iterations "
        'may not leave (docs/methods/hp-scp.md, "Guess").',
    )
    hold_final_time: bool = Field(
        True,
        description="With a final_time_guess_s, hold the final time there until the iterate is "
        "feasible, then free it.",
    )
    weight_virtual_control: float = Field(
        1.0e4,
        gt=0,
        description="Weight of the L1 virtual control on the dynamics, path, zone and terminal "
        "rows (an exact penalty: large enough that it vanishes at a feasible optimum).",
    )
    weight_virtual_control_initial: float = Field(
        1.0e4,
        gt=0,
        description="Virtual-control weight of the first iteration, raised by "
        "virtual_control_growth per iteration up to weight_virtual_control: a light penalty "
        "lets the objective shape the first steps.",
    )
    virtual_control_growth: float = Field(
        2.0, ge=1.0, le=100.0, description="Factor of the virtual-control weight per iteration."
    )
    virtual_control_steering: float = Field(
        3.0,
        ge=0.0,
        le=1.0e3,
        description="Steer the virtual-control weight to this many times the largest "
        "multiplier of the relaxed rows (at most weight_virtual_control; 0 = the schedule "
        "alone). An exact penalty needs only a weight above the multipliers; a far heavier "
        "one lets round-off-sized defects outweigh the objective in the ratio test.",
    )
    weight_trust_region: float = Field(
        30.0,
        gt=0,
        description="Initial weight of the quadratic trust-region penalty on the scaled changes.",
    )
    globalization: Literal["ratio", "paper"] = Field(
        "ratio",
        description="Step globalization: paper 003's (hard trust region, then the variable "
        "quadratic penalty once the objective oscillates, with a non-monotone filter line "
        "search), or SCvx's ratio test on the penalized cost with a quadratic trust penalty.",
    )
    penalty_rule: Literal["line_search", "direction_history"] = Field(
        "line_search",
        description="How the penalty weight adapts once the objective oscillates: halved after "
        "a whole step that lowered the objective and doubled otherwise, or paper 003 eqs. 77-79 "
        "(theta from the history of the step lengths; it grows without bound as the steps "
        "shrink, so its steps stop short of a stationary point).",
    )
    second_order: bool = Field(
        True,
        description="Add the convexified curvature of the collocation rows' Lagrangian (from "
        "the last subproblem's multipliers) to the step's quadratic term: an SQP step, whose "
        "model the ratio test then judges with its curvature.",
    )
    second_order_corrections: int = Field(
        2,
        ge=0,
        le=5,
        description="Second-order corrections per step: subproblems re-solved about the "
        "candidate with the final time held while they lower the penalized cost (each one "
        "conic solve).",
    )
    trust_box: bool = Field(
        False, description="Add paper 003's hard trust region (its delta per state)."
    )
    acceptance: Literal["ratio", "always"] = Field(
        "ratio",
        description="Step acceptance: SCvx's ratio test, or every step (PTR: the penalty "
        "weight alone keeps steps in the region where the model holds).",
    )
    weight_trust_region_min: float = Field(
        1.0e-6,
        gt=0,
        description="Smallest trust-region weight; a step is converged only once it is small at "
        "this weight (a small step at a heavier weight lightens it instead).",
    )
    weight_rate_regularization: float = Field(
        0.0,
        ge=0,
        description="Weight of the mean squared bank and alpha rates (per (deg/s)^2) added to "
        "the objective: smooths the rates at a small cost in the objective; 0 = off.",
    )
    stop_tolerance: HpStopTolerance = Field(
        default_factory=HpStopTolerance, description="Convergence test of the iteration."
    )
    defect_tolerance: float = Field(
        1.0e-6,
        gt=0,
        description="Largest nonlinear collocation defect (scaled units) of a converged iterate.",
    )
    between_points: Literal["always", "staged"] = Field(
        "always",
        description="Hold bank and alpha within their bounds and rate bounds on the whole of "
        "each interval's polynomial (through the Bernstein coefficients) and sample the path "
        "limits between the points: from the first iteration, or only once the run has "
        "converged with them at the points ('staged'; measured on the paper's case: a lower "
        "final time in about twice the iterations).",
    )
    mesh: Literal["adaptive", "fixed"] = Field(
        "adaptive",
        description="Mesh strategy: split the intervals whose propagated error or excess between "
        "points is over tolerance once the iterate is nearly feasible (paper 003 stage 3), or "
        "keep the initial mesh.",
    )
    mesh_error_tolerance: float = Field(
        1.0e-2,
        gt=0,
        description="Largest end-state error of an interval flown through the nonlinear "
        "dynamics from its first point, in trust units (1 km, 0.5 deg, 50 m/s, ...).",
    )
    mesh_excess_tolerance: float = Field(
        2.0e-3,
        gt=0,
        description="Largest relative excess of a bound or path limit between points.",
    )
    max_mesh_points: int = Field(
        800, ge=3, le=2000, description="Most points the refined mesh may have."
    )

    @model_validator(mode="after")
    def _mesh_fits(self) -> HpScpOptions:
        if self.nodes - 1 < self.intervals:  # below degree 1: name the count that is short
            raise_problems(
                "HpScpOptions",
                [
                    FieldProblem(
                        ("nodes",),
                        "too_few_nodes",
                        f"{self.intervals} intervals of degree 1 at least need "
                        f"{self.intervals + 1} points or more (intervals + 1); give nodes >= "
                        f"{self.intervals + 1} or fewer intervals",
                        self.nodes,
                    )
                ],
            )
        if (self.nodes - 1) % self.intervals != 0:
            raise_problems(
                "HpScpOptions",
                [
                    FieldProblem(
                        ("intervals",),
                        "mesh_shape",
                        f"nodes - 1 ({self.nodes - 1}) must be a multiple of intervals "
                        f"({self.intervals}): every interval has the same degree",
                        self.intervals,
                    )
                ],
            )
        return self

    @property
    def degree(self) -> int:
        """Polynomial degree of each interval of the initial mesh."""
        return (self.nodes - 1) // self.intervals
