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


class ResultDocument(BaseModel):
    """Trajectory with units, objective, verification, convergence history, timing, provenance."""

    model_config = ConfigDict(extra="forbid")

    schema_version: Literal["1.0"] = "1.0"
    status: ResultStatus
    failure: Failure | None = None
    method: str
    objective: ObjectiveValue | None = None
    trajectory: dict[str, Any] | None = Field(
        None,
        description="Columns at the optimizer's nodes: time_s, altitude_m, longitude_deg, "
        "latitude_deg, velocity_m_s, flight_path_angle_deg, heading_deg, bank_deg, alpha_deg, "
        "heat_rate_W_m2, dynamic_pressure_Pa, load_factor_g (and energy for energy methods); "
        "'units' maps each column to its unit.",
    )
    verification: dict[str, Any] | None = Field(
        None, description="Propagation through the nonlinear dynamics and the checks on it."
    )
    history: list[dict[str, Any]] = Field(default_factory=list)
    timing: Timing
    provenance: dict[str, Any] = Field(default_factory=dict)
