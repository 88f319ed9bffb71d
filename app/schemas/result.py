"""The result document: what a solve returns, as stored by the service and written by the CLI."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

ResultStatus = Literal["succeeded", "failed", "cancelled", "timed_out"]


class Failure(BaseModel):
    """Why a solve did not succeed: a stable code and a readable message."""

    code: str = Field(
        ...,
        description="e.g. infeasible, numerical_error, max_iterations, "
        "time_limit, verification_failed, cancelled, invalid_problem",
    )
    message: str


class ObjectiveValue(BaseModel):
    """The objective's value on the optimized trajectory (and after propagation when known)."""

    name: str = Field(..., description="Objective term name, or weighted_sum for several terms.")
    value: float | None
    units: str
    propagated_value: float | None = Field(
        None, description="Same quantity on the propagated trajectory, where it is defined."
    )
    terms: dict[str, float] = Field(default_factory=dict, description="Each term's value.")


class Timing(BaseModel):
    """Where the time went: the whole optimization, the conic solver's share, verification."""

    wall_s: float = Field(..., description="Optimization wall time (SCP loop), s.")
    conic_solve_s: float = Field(..., description="Sum of the conic solver's own solve times, s.")
    iterations: int
    verification_s: float = Field(0.0, description="Propagation and checks, s.")
    total_s: float = Field(0.0, description="Whole solve including model building, s.")


Number = float | None
"""A finite number, or null where the value was NaN or infinite (JSON has neither)."""


class HistoryRecord(BaseModel):
    """One SCP iteration: cost, step size, conic solve, timings (the worker's IterationRecord).

    Methods may add fields; ``extra`` holds method-specific diagnostics.
    """

    model_config = ConfigDict(extra="allow")

    iteration: int = Field(..., description="1 for the first iteration of the attempt.")
    cost: Number = Field(
        None, description="Objective on the iterate: SI units for one term, else normalized."
    )
    cost_terms: dict[str, Number] = Field(
        default_factory=dict, description="Each term of the subproblem's cost."
    )
    objective_value: Number = Field(
        None, description="The problem's own objective on the new reference, SI units."
    )
    max_state_change: dict[str, Number] | Number = Field(
        None, description="Largest change of each state over the nodes (SI units, degrees)."
    )
    trust_region_slack: Number = None
    virtual_control_norm: Number = None
    linearization_error: Number = Field(
        None, description="Largest |f - f_L| over nodes and states (nondimensional)."
    )
    nodes_post_corrected: int | None = Field(
        None, description="(node, state) pairs whose step was shortened."
    )
    relaxation_gap: Number = Field(
        None, description="Largest 1 - |u| over nodes (0 when the control cone is tight)."
    )
    conic_status: str | None = Field(None, description='The conic solver\'s status, "optimal".')
    conic_solver: str | None = None
    conic_solve_s: Number = None
    conic_setup_s: Number = None
    iteration_wall_s: Number = None
    conic_solver_setup_s: Number = None
    subproblem_cost: Number = None
    extra: dict[str, Any] = Field(default_factory=dict, description="Method diagnostics.")


class Trajectory(BaseModel):
    """The optimized trajectory as columns, one value per node, each column's unit in ``units``.

    Columns are present when the problem defines them (no heat rate without a heat model,
    ``energy`` for energy-domain methods only).
    """

    model_config = ConfigDict(extra="allow")

    nodes: int | None = Field(None, description="Number of nodes (length of every column).")
    units: dict[str, str] = Field(default_factory=dict, description="Unit of each column.")
    time_s: list[Number] | None = None
    altitude_m: list[Number] | None = None
    longitude_deg: list[Number] | None = None
    latitude_deg: list[Number] | None = None
    velocity_m_s: list[Number] | None = None
    flight_path_angle_deg: list[Number] | None = None
    heading_deg: list[Number] | None = None
    bank_deg: list[Number] | None = None
    alpha_deg: list[Number] | None = None
    heat_rate_W_m2: list[Number] | None = None
    dynamic_pressure_Pa: list[Number] | None = None
    load_factor_g: list[Number] | None = None
    energy: list[Number] | None = None


class ResultDocument(BaseModel):
    """Trajectory with units, objective, verification, convergence history, timing, provenance."""

    model_config = ConfigDict(extra="forbid")

    schema_version: Literal["1.0"] = "1.0"
    status: ResultStatus
    failure: Failure | None = None
    method: str
    objective: ObjectiveValue | None = None
    trajectory: Trajectory | None = Field(
        None, description="The optimizer's nodes; absent when the solve produced none."
    )
    verification: dict[str, Any] | None = Field(
        None,
        description="Propagation of the optimized controls through the nonlinear dynamics and "
        "the checks on it: feasible, final_state, terminal errors against the targets and "
        "tolerances, path maxima against their limits, no-fly zone clearances.",
    )
    history: list[HistoryRecord] = Field(
        default_factory=list, description="Every SCP iteration of the attempt, in order."
    )
    timing: Timing
    provenance: dict[str, Any] = Field(default_factory=dict)
