"""Options of the Chebyshev pseudospectral SCvx with the lift vector as control, free final time
(paper 001, ``cheb-scvx``)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from app.schemas.base import FieldProblem, raise_problems
from app.schemas.methods.common import BoundedOptions, ScpRunOptions

PAPER_RESOLUTION = (201, 20)
"""CGL points and intervals when a document gives neither: paper 001's flight resolution."""
HEAT_LOAD_RESOLUTION = (401, 40)
"""CGL points and intervals when a document gives neither and minimizes a heat load: its bank
pulses need intervals half as long (docs/methods/cheb-scvx.md, "User problems")."""


def default_resolution(heat_load: bool) -> tuple[int, int]:
    """cheb-scvx's (nodes, intervals) for a problem of this class when its document gives
    neither."""
    return HEAT_LOAD_RESOLUTION if heat_load else PAPER_RESOLUTION


class ChebStopTolerance(BoundedOptions):
    """Convergence test (paper 001 eq. 43): no point moves more than these between iterations,
    nor the final time. The paper's own values (0.03 rad of longitude and latitude, 19 km of
    altitude, 316 m/s) stop far from the optimum; these defaults are the accuracy a mission
    design asks of the answer."""

    altitude_m: float = Field(50.0, gt=0, description="Altitude change tolerance, m.")
    longitude_deg: float = Field(0.01, gt=0, description="Longitude change tolerance, deg.")
    latitude_deg: float = Field(0.01, gt=0, description="Latitude change tolerance, deg.")
    velocity_m_s: float = Field(1.0, gt=0, description="Speed change tolerance, m/s.")
    flight_path_angle_deg: float = Field(
        0.05, gt=0, description="Flight path angle change tolerance, deg."
    )
    heading_deg: float = Field(0.05, gt=0, description="Heading change tolerance, deg.")
    final_time_s: float = Field(0.5, gt=0, description="Final time change tolerance, s.")


class ChebTrustRegion(BoundedOptions):
    """Half-widths of the initial trust box (paper 001 eq. 30, 44: 0.2 Re of map distance, 10 km,
    5000 m/s, 30 deg), scaled each iteration by the SCvx ratio test."""

    altitude_m: float = Field(10_000.0, gt=0, description="Altitude half-width, m.")
    longitude_deg: float = Field(11.46, gt=0, description="Longitude half-width, deg.")
    latitude_deg: float = Field(11.46, gt=0, description="Latitude half-width, deg.")
    velocity_m_s: float = Field(5000.0, gt=0, description="Speed half-width, m/s.")
    flight_path_angle_deg: float = Field(30.0, gt=0, description="Flight path half-width, deg.")
    heading_deg: float = Field(30.0, gt=0, description="Heading half-width, deg.")
    lift_control: float = Field(
        0.5, gt=0, description="Half-width of each lift-vector component u1, u2, u3 (lambda units)."
    )
    final_time_s: float = Field(
        300.0, gt=0, description="Half-width of each segment's duration, s."
    )


class ChebScvxOptions(ScpRunOptions):
    """Paper 001's SCvx on Chebyshev-Gauss-Lobatto points with the lift vector as control."""

    name: Literal["cheb-scvx"] = Field("cheb-scvx", description="Method name.")
    nodes: int = Field(
        PAPER_RESOLUTION[0],
        ge=3,
        le=1000,
        description="CGL points of the flight (the intervals' degrees sum to nodes - 1); when a "
        f"document gives neither nodes nor intervals, {PAPER_RESOLUTION[0]} on "
        f"{PAPER_RESOLUTION[1]} intervals (paper 001's), {HEAT_LOAD_RESOLUTION[0]} on "
        f"{HEAT_LOAD_RESOLUTION[1]} for a heat-load objective; with "
        "waypoints, shared among the legs in proportion to their lengths. Each interval has "
        "degree 2 at least, so at least 2 x intervals + 1 (41 for the default 20 intervals; 3 "
        "for one interval, the fewest the method runs with).",
    )
    intervals: int = Field(
        PAPER_RESOLUTION[1],
        ge=1,
        le=999,
        description="CGL intervals of the flight, shared among the legs like the points; the "
        "intervals of a leg share its duration equally. 1 = paper 001's single Chebyshev "
        "interval (paper 001's own case needs some 200 points to fly as planned: its skipping "
        "flight amplifies any error of the nodes' interpolation).",
    )
    max_iterations: int = Field(150, ge=1, le=500, description="Most SCP iterations, 1..500.")
    final_time_guess_s: float | None = Field(
        None,
        gt=0,
        le=100_000,
        description="Flight time of the initial guess, s; none = the distance flown at the mean "
        "of the initial and terminal speeds (or the constant-control flight without a target).",
    )
    weight_virtual_control: float = Field(
        1.0e3,
        gt=0,
        description="Weight of the L1 virtual control and of the path, zone and waypoint slacks "
        "(an exact penalty: large enough that they vanish at a feasible optimum).",
    )
    trust_region: ChebTrustRegion = Field(
        default_factory=ChebTrustRegion, description="Initial trust box (paper 001 eq. 44)."
    )
    stop_tolerance: ChebStopTolerance = Field(
        default_factory=ChebStopTolerance, description="Convergence test (paper 001 eq. 43)."
    )
    weight_induced_drag: float = Field(
        1.0e-2,
        ge=0.0,
        description="Weight of the integral of u3 over each segment's [-1, 1] in the objective "
        "(its units: s, m/s, deg or MJ/m^2 per unit): a tie-breaker that keeps the relaxed "
        "cone u1^2 + u2^2 <= u3 tight where the objective is indifferent to the drag (a "
        "push-over at no lift); 0 = the paper's objective alone.",
    )
    weight_unused_lift: float = Field(
        0.3,
        ge=0.0,
        description="For a vehicle whose angle of attack follows a schedule (its lift vector "
        "(cos sigma, sin sigma) times the schedule's lift, relaxed to the unit disc): the "
        "weight of the lift share left unused, 1 - |(u1, u2)|, at each point in the "
        "objective's unit (linearized along the reference's direction). It drives the "
        "relaxation tight where the objective would rather fly less lift than the schedule "
        "gives, which no vehicle can; 0 = the relaxation alone.",
    )
    lift_manifold: bool = Field(
        True,
        description="A run that converges to controls that do not fly as planned, with the "
        "relaxed cone slack somewhere (u3 - u1^2 - u2^2 above 1e-3: lift the vehicle cannot "
        "leave unused), goes on with the lift vector on u3 = u1^2 + u2^2, linearized at each "
        "reference and held by a penalized slack, so that its answer is one the vehicle flies; "
        "false: the relaxation alone (and weight_lift_smoothing 0: the paper's run).",
    )
    weight_lift_smoothing: float = Field(
        10.0,
        ge=0.0,
        description="A run that converges to controls that do not fly as planned goes on with "
        "the sum of the squared changes of the lift vector between neighbouring points in the "
        "objective, this weight per unit of the objective's largest coefficient per scaled "
        "unit on the lift manifold, a tenth of it off the manifold (a tight cone). Where the "
        "objective is indifferent to how the vehicle sheds energy (a terminal speed held by "
        "the dynamic-pressure limit at the terminal altitude, a bank whose side does not "
        "matter) it picks a smooth bank among the equal answers; the converged objective is "
        "held as a bound (an exact penalty), so it only breaks ties; 0: none.",
    )
    path_margin: float = Field(
        0.02,
        ge=0.0,
        lt=1.0,
        description="A point's path limits enter the subproblem once the reference comes "
        "within this share of a limit (paper 001 sec. 3.4 adds them where violated: 0); a "
        "point once added stays.",
    )
    samples_between_points: int = Field(
        3,
        ge=0,
        le=20,
        description="Points of the states' interpolating polynomial sampled between "
        "neighbouring CGL points where the no-fly zones are also constrained.",
    )

    @model_validator(mode="after")
    def _degree_two(self) -> ChebScvxOptions:
        """Every interval needs degree 2 at least: fewer points than that are refused rather
        than raised to it behind the caller's back."""
        fewest = 2 * self.intervals + 1
        if self.nodes < fewest:
            raise_problems(
                "ChebScvxOptions",
                [
                    FieldProblem(
                        ("nodes",),
                        "too_few_nodes",
                        f"{self.intervals} intervals of degree 2 at least need {fewest} points "
                        f"or more (2 x intervals + 1); give nodes >= {fewest} or fewer intervals",
                        self.nodes,
                    )
                ],
            )
        return self
