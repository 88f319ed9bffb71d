"""Options of the time-domain SCP with exact FOH and an adaptive grid (paper 002, ``foh-ptr``)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from app.schemas.base import FieldProblem, raise_problems
from app.schemas.limits import MAX_ITERATIONS, MAX_NODES
from app.schemas.methods.common import BoundedOptions, ConicBackendName, ScpRunOptions

MIN_NODES = 9
"""The fewest nodes foh-ptr runs with (docs/problem-contract.md, "Method": measured)."""
BANK_ONLY_NODES = 40
"""Nodes when a document gives none, on a fixed final time with the bank the only control:
paper 002's."""
FINER_NODES = 80
"""Nodes when a document gives none, with a free final time or a held attitude state (an
optimized angle of attack, a polar's normalized lift): its flights need finer intervals
(docs/methods/foh-ptr.md, "Free final time", "An optimized angle of attack")."""
FREE_TIME_HEAT_LOAD_NODES = 120
"""Nodes when a document gives none, with a free final time and a heat-load objective: its
bank pulses need finer intervals still (docs/methods/foh-ptr.md, "Free final time")."""


def default_nodes(free_final_time: bool, heat_load: bool, held_attitude: bool) -> int:
    """foh-ptr's nodes for a problem of this class when its document gives none."""
    if free_final_time:
        return FREE_TIME_HEAT_LOAD_NODES if heat_load else FINER_NODES
    return FINER_NODES if held_attitude else BANK_ONLY_NODES


class FohStopTolerance(BoundedOptions):
    """Convergence test of the time-domain SCP: every node moves less than these between
    iterations, the interval lengths less than ``interval_s`` and the cost by less than
    ``relative_cost``. Tighter than paper 002's (1000 m, 1 deg, 1 deg, 100 m/s, 1 deg, 1 deg, 5 s)
    so that the converged nodes match their own propagation to Table 4's residuals."""

    altitude_m: float = Field(100.0, gt=0, description="Altitude change tolerance, m.")
    longitude_deg: float = Field(0.02, gt=0, description="Longitude change tolerance, deg.")
    latitude_deg: float = Field(0.02, gt=0, description="Latitude change tolerance, deg.")
    velocity_m_s: float = Field(5.0, gt=0, description="Speed change tolerance, m/s.")
    flight_path_angle_deg: float = Field(
        0.05, gt=0, description="Flight path angle change tolerance, deg."
    )
    heading_deg: float = Field(0.05, gt=0, description="Heading change tolerance, deg.")
    bank_deg: float = Field(2.0, gt=0, description="Bank angle change tolerance, deg.")
    angle_of_attack_deg: float = Field(
        0.5, gt=0, description="Angle of attack change tolerance where it is optimized, deg."
    )
    normalized_lift: float = Field(
        0.005, gt=0, description="Normalized-lift change tolerance of a parabolic polar (1)."
    )
    bank_dynamic_pressure_fraction: float = Field(
        0.01,
        ge=0,
        lt=1,
        description="The bank tolerance applies only at nodes whose dynamic pressure is at least "
        "this fraction of the iterate's peak: the bank turns the lift, which scales with the "
        "dynamic pressure, so below 1 % of the peak a bank change redirects under 1 % of the "
        "peak lift and swings there (the thin early arc) move no state beyond its own "
        "tolerance; 0 tests the bank at every node.",
    )
    interval_s: float = Field(2.0, gt=0, description="Interval length change tolerance, s.")
    relative_cost: float = Field(
        1e-3, gt=0, description="Relative change of the objective below which it has settled."
    )


class FohPtrOptions(ScpRunOptions):
    """Time-domain SCP with exact first-order-hold discretization and an adaptive time grid
    (Ma, Chen, Wang & Zhang 2023, paper 002): bank angle as a state, bank rate as the control,
    penalized trust region (PTR). Departures from the paper are listed in docs/methods/foh-ptr.md.
    """

    name: Literal["foh-ptr"] = Field("foh-ptr", description="Method name.")
    conic_backend: ConicBackendName = Field(
        "piqp",
        description='Subproblem solver: "piqp" (the default here: every subproblem of this method '
        "is a quadratic program; PIQP, with Clarabel for whatever PIQP does not solve), "
        '"clarabel" directly, or "cvxpy" (Clarabel through cvxpy).',
    )
    nodes: int = Field(
        BANK_ONLY_NODES,
        ge=MIN_NODES,
        le=MAX_NODES,
        description=f"Temporal nodes (N + 1 for N intervals), {MIN_NODES}..{MAX_NODES}; when "
        f"a document gives none, by its class: {BANK_ONLY_NODES} (paper 002's) on a fixed final "
        f"time with the bank alone, {FINER_NODES} with a free final time or an optimized angle "
        f"of attack or a polar's lift, {FREE_TIME_HEAT_LOAD_NODES} with a free final time and a "
        "heat-load objective. "
        f"{MIN_NODES} is the fewest with which the method starts on its built-in flights: "
        "with fewer, intervals of more than 200 s of a 1600 s flight, its constant-bank guess "
        "(two RK4 steps per interval) blows up and the first subproblem breaks down.",
    )
    max_iterations: int = Field(
        100,
        ge=1,
        le=MAX_ITERATIONS,
        description=f"Most SCP iterations of each start, 1..{MAX_ITERATIONS} (at most 43 a start "
        "on the variant suite, 20-74 on user-like problems, bench/iteration_budgets.py).",
    )
    grid: Literal["adaptive", "uniform"] = Field(
        "adaptive",
        description='"adaptive": interval lengths are decision variables (time dilation, paper '
        '002 sec. 3.1, the paper\'s method); "uniform": fixed equal intervals.',
    )
    discretization: Literal["exact_foh", "trapezoid"] = Field(
        "exact_foh",
        description='"exact_foh": inverse-free exact FOH maps stitched to the propagated '
        'reference (paper 002 Theorem 1, eq. 24); "trapezoid": the trapezoidal rule (for '
        "comparison; needs many more nodes).",
    )
    foh_substeps: int = Field(
        8,
        ge=1,
        le=200,
        description="Fixed RK4 steps per interval of the exact FOH integration (all intervals "
        "at once).",
    )
    intersample_constraints: bool = Field(
        True,
        description="Also impose the linearized path limits and no-fly zones between the nodes: "
        "one row per interval bounding the smooth maximum over the samples of the exact FOH "
        "integration (exact_foh only). The paper imposes them at the nodes only; see "
        "docs/methods/foh-ptr.md.",
    )
    intersample_smooth_max: Literal["exact", "conservative"] = Field(
        "conservative",
        description='Value of each between-node row: "exact", the worst sample (the smooth '
        "maximum g_KS = g_max + d ln sum_j exp((g_j - g_max) / d) less its offset at the "
        "reference; only the row's gradient is smoothed), so a converged row holds the sampled "
        'constraint exactly; "conservative", g_KS itself, above the worst sample by up to '
        "d ln J (J = foh_substeps + 1 samples), a bias toward that bound as the mesh is refined. "
        'Default "conservative": with "exact" paper 002 case 1 at 40 nodes needs 16 iterations '
        "(its acceptance is at most 15); see docs/methods/foh-ptr.md for both, measured.",
    )
    intersample_width_log: float = Field(
        0.002,
        gt=0,
        le=0.1,
        description="Smoothing width d of the between-node path-limit rows, in ln(p / p_max): "
        "how far below the worst sample the other samples still weigh in the row's gradient "
        '(0.002: 0.2 % of the limit). With "conservative" the row is also above the worst '
        "sample by up to d ln J (0.44 % with 9 samples).",
    )
    intersample_width_zone_deg: float = Field(
        0.005,
        gt=0,
        le=1,
        description="Smoothing width d of the between-node no-fly-zone rows, deg of the zone's "
        'metric (0.005 deg, a tenth of the 0.05 deg intrusion bound). With "conservative" the '
        "row is also above the worst sample by up to d ln J (0.011 deg with 9 samples).",
    )
    interval_min_s: float | None = Field(
        None,
        gt=0,
        description="Shortest interval of the adaptive grid (Delta_min), s; none = paper 002's "
        "10 s as a multiple of its mean interval (1600 s / 39): 0.244 t_f / N (10 s for the "
        "paper's 40 nodes, 1.0 s for 400).",
    )
    interval_max_s: float | None = Field(
        None,
        gt=0,
        description="Longest interval of the adaptive grid (Delta_max), s; none = paper 002's "
        "150 s as a multiple of its mean interval: 3.66 t_f / N.",
    )
    interval_trust_s: float | None = Field(
        None,
        gt=0,
        description="Largest change of an interval length per iteration (DeltaT_max), s; none = "
        "paper 002's 50 s as a multiple of its mean interval: 1.22 t_f / N.",
    )
    weight_trust_region: float = Field(
        0.1,
        gt=0,
        description="Initial weight w_tr of the penalized trust region sum ||dz||^2 + ||dw||^2 "
        "on scaled deviations.",
    )
    weight_trust_region_min: float = Field(
        1.0e-5, gt=0, description="Smallest trust weight the adaptation may reach."
    )
    trust_defect_target: float = Field(
        10.0,
        gt=0,
        description="Defect (a step's propagation minus its nodes, largest scaled state gap) the "
        "trust weight aims at: after each step w_tr is multiplied by sqrt(defect / target), "
        "clipped to [1/trust_factor, trust_factor].",
    )
    trust_factor: float = Field(
        8.0,
        ge=1,
        description="Largest factor by which the trust weight changes per iteration; 1 keeps it "
        "fixed.",
    )
    trust_reversal_cosine: float = Field(
        0.1,
        ge=0,
        le=1,
        description="When a step points back along the previous one (cosine below minus this), "
        "the iterates are swinging between two points: the trust weight then grows by "
        "trust_factor whatever the defect.",
    )
    second_order: bool = Field(
        True,
        description="Add the Lagrangian curvature of the exact FOH interval maps to the "
        "subproblem (an SQP step, with the multipliers of the last subproblem); exact_foh only. "
        "false gives paper 002's first-order PTR step; see docs/methods/foh-ptr.md.",
    )
    second_order_substeps: int = Field(
        2,
        ge=1,
        le=50,
        description="RK4 steps per interval of the integrations that difference the maps' "
        "Jacobians for the curvature (it only shapes the step, not the dynamics' accuracy).",
    )
    weight_trust_interval: float = Field(
        100.0,
        ge=0,
        description="Weight w_tr2 of sum (s - s_bar)^2 on scaled interval changes (paper 002's "
        "J_tr,2, which the paper omits; it damps the nearly free sliding of nodes along the "
        "trajectory, which otherwise creeps and stops short: paper 002 case 1 at 40 nodes "
        "970.15 m/s with 100, 968.53 with 10; see docs/methods/foh-ptr.md).",
    )
    weight_trust_final_time: float = Field(
        1.0,
        ge=0,
        description="With a free final time, the weight of N m^2 on the intervals' mean scaled "
        "change m (the final time's), in place of weight_trust_interval, which then damps only "
        "the sliding of the nodes about that mean: at 100 the final time moved about 1 s an "
        "iteration and a glide that needed 600 s more stopped at the iteration limit.",
    )
    weight_nonlinear: float = Field(
        0.0,
        ge=0,
        description="Weight w_nl of the second-order path-limit term sum (V - V_bar)^2 / V_bar^2 "
        "(paper 002 eq. 26). With second_order it only damps the step (0 converges fastest); "
        "the first-order step needs it (about 1e4).",
    )
    weight_no_fly_zone: float = Field(
        1.0,
        ge=0,
        description="Weight w_NFZ of the squared distance to a zone's centre over the node window "
        "around the closest approach (paper 002 sec. 3.3.2), per zone radius squared.",
    )
    no_fly_zone_window: int = Field(
        3, ge=0, le=50, description="Nodes on each side of the closest approach in the window."
    )
    no_fly_zone_engage_deg: float = Field(
        0.0,
        ge=0,
        description="The distance penalty acts only once the reference comes within this of a "
        "zone's edge, deg; 0: once it touches or enters the zone (the penalty pulls toward the "
        "centre, so acting on a zone the path clears would cost the objective).",
    )
    weight_virtual_control: float = Field(
        1.0e3,
        gt=0,
        description="Weight of the L1 buffer on each fixed terminal condition (virtual control, "
        "per scaled unit); keeps early subproblems feasible, must vanish at convergence.",
    )
    weight_virtual_control_initial: float = Field(
        30.0,
        gt=0,
        description="Virtual-control weight of the first iteration; it grows by "
        "virtual_control_growth per iteration up to weight_virtual_control (continuation: "
        "early linearizations close the terminal miss gradually).",
    )
    virtual_control_growth: float = Field(
        2.0, ge=1, description="Factor by which the virtual-control weight grows per iteration."
    )
    initial_bank_deg: float | None = Field(
        None,
        ge=-90,
        le=90,
        description="Constant bank of the propagated initial reference, deg; none = the best of "
        "a sweep of constant banks (closest to the terminal conditions).",
    )
    bank_sign_starts: bool = Field(
        True,
        description="When the initial bank is free (no initial_bank_deg, no fixed initial "
        "bank), run the SCP from the closest constant bank of each sign and keep the better "
        "converged answer (the result's starts say which): the bank's sign in the thin early arc "
        "picks between local optima (paper 002 case 1 at 120 nodes: 969.8 against 970.6 m/s). "
        "false: one start, about half the time.",
    )
    stop_tolerance: FohStopTolerance = Field(
        default_factory=FohStopTolerance,
        description="Per-state change below which the iteration has converged.",
    )

    @model_validator(mode="after")
    def _second_order_needs_exact_maps(self) -> FohPtrOptions:
        if self.second_order and self.discretization != "exact_foh":
            raise_problems(
                "FohPtrOptions",
                [
                    FieldProblem(
                        ("second_order",),
                        "second_order_discretization",
                        "second_order needs discretization exact_foh (the trapezoidal maps have "
                        "no curvature term); set second_order to false",
                        self.second_order,
                    )
                ],
            )
        return self
