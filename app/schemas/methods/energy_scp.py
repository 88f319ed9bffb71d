"""Options of the energy-domain SCP with post-correction (paper 000, method ``energy-scp``)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from app.schemas.limits import MAX_ITERATIONS, MAX_NODES
from app.schemas.methods.common import BoundedOptions, ScpRunOptions


class EnergyStopTolerance(BoundedOptions):
    """Convergence test of energy-domain SCP: every state changes less than its tolerance.

    Values from Jung, Kim, Choi and Lee, sec. 4; the paper lists four values for five states,
    the heading takes the flight path angle's.
    """

    altitude_m: float = Field(100.0, gt=0, description="Altitude change tolerance, m.")
    longitude_deg: float = Field(0.6, gt=0, description="Longitude change tolerance, deg.")
    latitude_deg: float = Field(0.6, gt=0, description="Latitude change tolerance, deg.")
    flight_path_angle_deg: float = Field(
        1.0, gt=0, description="Flight path angle change tolerance, deg."
    )
    heading_deg: float = Field(1.0, gt=0, description="Heading change tolerance, deg.")
    relative_cost: float = Field(
        3e-5,
        gt=0,
        description="Stationarity: the objective changed by less than this fraction of its "
        "value over the last iteration (the state test alone takes a slow creep towards the "
        "optimum for convergence).",
    )


class EnergyScpOptions(ScpRunOptions):
    """Energy-domain sequential convex programming with post-correction (Jung et al.).

    Energy is the independent variable, path limits become lower bounds on radius; the trust
    region weight and post-correction step are the paper's (Table 1, sec. 4). Soft terminal
    weights come from the terminal conditions themselves. Departures from the paper, with
    their reasons, are listed in docs/methods/energy-scp.md.
    """

    name: Literal["energy-scp"] = Field("energy-scp", description="Method name.")
    nodes: int = Field(
        121,
        ge=3,
        le=MAX_NODES,
        description=f"Discretization nodes (grid points: N + 1 for N intervals), 3..{MAX_NODES}: "
        "3 is the fewest the method iterates with (with 2 its first step leaves the physical "
        "range); below about 20 the coarse energy grid often breaks down after some "
        "iterations (diverged, numerical_error).",
    )
    max_iterations: int = Field(
        200,
        ge=1,
        le=MAX_ITERATIONS,
        description=f"Most SCP iterations, 1..{MAX_ITERATIONS} (the relaxed trust region and "
        "the stationarity test need more than the paper's fixed weight: 15-46 on the variant "
        "suite, 42-163 on user-like problems, bench/iteration_budgets.py).",
    )
    grid: Literal["time_adaptive", "uniform"] = Field(
        "time_adaptive",
        description='Node placement in energy: "uniform" as in the paper, or "time_adaptive": '
        "start from a glide-time estimate and re-space the nodes evenly in flight time after "
        "the second iteration, so the terminal maneuver is resolved.",
    )
    stop_tolerance: EnergyStopTolerance = Field(
        default_factory=EnergyStopTolerance,
        description="Per-state change below which the iteration has converged.",
    )
    defect_correction: bool = Field(
        True,
        description="Correct the trapezoid by its error at the reference: each interval is "
        "integrated from its node under the bank the verification flies (RK4) and the "
        "difference is added to the dynamics rows, so a converged trajectory obeys the exact "
        "dynamics between nodes at any node count and the running costs are the exact "
        "integrals (false: the paper's plain trapezoid).",
    )
    post_correction: bool = Field(
        True, description="Shorten the step where the linearization error is large."
    )
    post_correction_step: float = Field(
        0.7, gt=0, le=1, description="Post-correction step length beta, in (0, 1]."
    )
    linearization_error_threshold: float = Field(
        1e-3,
        gt=0,
        description="Nondimensional linearization error above which a node is post-corrected.",
    )
    weight_regularization: float = Field(
        1000.0,
        ge=0,
        description="Weight of the cone-tightness regularization: a reward on the bank-plane "
        "control along its previous direction (the linearization of |u|), which keeps "
        "(cos sigma, sin sigma) on the unit circle (paper 000 eq. 22). Per unit energy. After "
        "trust_hold_iterations it is halved per iteration at nodes whose control stays on the "
        "circle, down to weight_regularization_min, and raised again where a control falls "
        "inside the disc: the reward also resists turning the bank, which slows the iterates "
        "wherever the optimum swings it.",
    )
    weight_regularization_min: float = Field(
        0.05, ge=0, description="Lightest per-node regularization weight (see above)."
    )
    weight_control_smoothness: float = Field(
        0.1,
        ge=0,
        description="Weight of the penalty on the step of the control changes between nodes "
        "(the change of u_{i+1} - u_i from one iteration to the next): damps node-to-node "
        "bank chattering and vanishes at convergence, so it does not bias the optimum.",
    )
    bank_rate_limit_deg_s: float | None = Field(
        5.0,
        gt=0,
        description="Bound on the bank rate between nodes, deg/s, as |u_{i+1} - u_i| <= "
        "2 sin(rate * dt_i / 2) with dt_i the interval's flight time on the reference: a "
        "discrete solution cannot chatter the bank from node to node (which the trapezoid "
        "averages into lift the vehicle cannot fly). null: no bound. The default is above the "
        "bank rates of the reference optima (3.1 deg/s on the built-in scenario).",
    )
    bank_step_max_deg: float = Field(
        90.0,
        gt=0,
        le=180,
        description="Largest bank change between neighbouring nodes, deg (as the chord "
        "|u_{i+1} - u_i| <= 2 sin(angle / 2)): the trapezoid averages the two nodes' lift "
        "vectors while the flown bank sweeps between them, and the two differ by ~angle^2/6 of "
        "the lift; this keeps that discretization error small and vanishes as the mesh is "
        "refined (a fixed angle per interval allows ever faster rates).",
    )
    chatter_angle_deg: float = Field(
        10.0,
        gt=0,
        description="Stop rule against chatter: a step is not called converged while the bank "
        "zigzags (three consecutive bank steps between nodes alternate in sign, each larger "
        "than this angle, deg); the nodes are counted in the history as bank_chatter_nodes.",
    )
    weight_trust_region: float = Field(
        0.005,
        gt=0,
        description="Weight on the trust-region slack (w_tr) for the first "
        "trust_hold_iterations; then it is multiplied by trust_relax_factor per iteration down "
        "to weight_trust_region_min (heavier again after a step that swings back); a step is "
        "called converged only once the weight has reached that floor.",
    )
    weight_trust_region_min: float = Field(
        1e-5, gt=0, description="Lightest trust-region weight (see weight_trust_region)."
    )
    trust_relax_factor: float = Field(
        0.25,
        gt=0,
        le=1,
        description="Factor on the trust-region weight per iteration after the held ones; 1 "
        "keeps the paper's fixed weight.",
    )
    trust_hold_iterations: int = Field(
        3,
        ge=0,
        description="Iterations at the full trust-region and regularization weights before "
        "both are relaxed.",
    )
    weight_terminal_penalty: float | None = Field(
        20.0,
        gt=0,
        description="Fixed terminal conditions are held by an exact L1 penalty on their miss, "
        "this weight per trust-region unit of the state, instead of equality rows: an "
        "equality on a far target makes the first steps leap (tens of degrees of longitude) "
        "and the iterates settle on a worse local optimum. The miss counts as virtual "
        "control, so a result converges only once it vanishes, and a target that cannot be "
        "reached is reported with its miss. null: equality rows (the paper's).",
    )
    virtual_control: Literal["off", "auto", "on"] = Field(
        "auto",
        description='Dynamics slack against artificial infeasibility: "auto" adds it only '
        "when a subproblem is infeasible without it.",
    )
    weight_virtual_control: float = Field(
        1e5,
        gt=0,
        description="Weight on the virtual-control (dynamics slack) norm: an exact penalty, "
        "so it must exceed what a unit of slack buys of the objective (1e4 let a maximum final "
        "longitude buy 0.7 deg with slack it never gave back, docs/methods/energy-scp.md).",
    )
