"""Solution methods and their options; each method is one options class in ``METHOD_OPTIONS``.

To add a method: define its options model with a ``name`` literal, register it in
``METHOD_OPTIONS`` and add it to the ``MethodSpec`` union.
"""

from __future__ import annotations

from typing import Annotated, Any, Final, Literal

from pydantic import BeforeValidator, Field

from app.schemas.base import StrictModel, untagged_errors
from app.schemas.limits import MAX_ITERATIONS, MAX_NODES, MAX_TIME_LIMIT_S

DEFAULT_METHOD: Final[str] = "energy-scp"
"""Method used when a document names none."""


class EnergyStopTolerance(StrictModel):
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


class EnergyScpOptions(StrictModel):
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
        description=f"Discretization nodes (grid points: N + 1 for N intervals), 3..{MAX_NODES}.",
    )
    grid: Literal["time_adaptive", "uniform"] = Field(
        "time_adaptive",
        description='Node placement in energy: "uniform" as in the paper, or "time_adaptive": '
        "start from a glide-time estimate and re-space the nodes evenly in flight time after "
        "the second iteration, so the terminal maneuver is resolved.",
    )
    max_iterations: int = Field(
        30, ge=1, le=MAX_ITERATIONS, description=f"Most SCP iterations, 1..{MAX_ITERATIONS}."
    )
    time_limit_s: float = Field(
        120.0,
        gt=0,
        le=MAX_TIME_LIMIT_S,
        description=f"Wall-clock limit of the whole solve, s, in (0, {MAX_TIME_LIMIT_S:g}].",
    )
    conic_backend: Literal["clarabel", "cvxpy"] = Field(
        "clarabel",
        description='Second-order cone solver interface: "clarabel" directly, or through cvxpy.',
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
        description="Wall-clock limit of each convex subproblem, s; none = only the overall limit.",
    )
    stop_tolerance: EnergyStopTolerance = Field(
        default_factory=EnergyStopTolerance,
        description="Per-state change below which the iteration has converged.",
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
        "(cos sigma, sin sigma) on the unit circle (paper 000 eq. 22). Per unit energy.",
    )
    weight_control_smoothness: float = Field(
        0.1,
        ge=0,
        description="Weight of the penalty on control changes between nodes; suppresses the "
        "node-to-node bank chattering by which a discrete solution can mimic reduced lift.",
    )
    weight_trust_region: float = Field(
        0.005, gt=0, description="Weight on the trust-region slack (w_tr)."
    )
    virtual_control: Literal["off", "auto", "on"] = Field(
        "auto",
        description='Dynamics slack against artificial infeasibility: "auto" adds it only '
        "when a subproblem is infeasible without it.",
    )
    weight_virtual_control: float = Field(
        1e4, gt=0, description="Weight on the virtual-control (dynamics slack) norm."
    )


METHOD_OPTIONS: dict[str, type[StrictModel]] = {
    "energy-scp": EnergyScpOptions,
}
"""Options model of every method, by method name."""

METHOD_NAMES: tuple[str, ...] = tuple(METHOD_OPTIONS)
"""Names of the available methods."""


def _default_name(value: Any) -> Any:
    """A method object without ``name`` selects the default method."""
    if isinstance(value, dict) and "name" not in value:
        return {**value, "name": DEFAULT_METHOD}
    return value


MethodSpec = Annotated[
    Annotated[EnergyScpOptions, Field(discriminator="name")],
    untagged_errors("name"),
    BeforeValidator(_default_name),
]
"""The solution method and its options, selected by ``name``."""
