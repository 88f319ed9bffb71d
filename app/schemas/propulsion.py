"""Propulsion of a powered entry vehicle: thrust, specific impulse, thrust lag and dry mass."""

from __future__ import annotations

from typing import Annotated, Final

from pydantic import Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from app.schemas import bounds
from app.schemas.base import FieldProblem, StrictModel, raise_problems

STANDARD_GRAVITY_M_S2: Final = 9.80665
"""Standard gravity, m/s^2: the one specific impulse is defined with (not the planet's g0)."""


class Propulsion(StrictModel):
    """A throttleable rocket engine, as in paper 004's Space Shuttle skip entry.

    The thrust T acts along the vehicle's body axis (at the angle of attack to the velocity) and
    burns propellant: dm/dt = -T / (isp_s * 9.80665). With propulsion the vehicle's mass is a
    state that starts at ``vehicle.mass_kg``.
    """

    max_thrust_n: float = Field(
        ...,
        gt=0,
        le=bounds.THRUST_MAX_N,
        description=f"Largest thrust the engine gives, N, in (0, {bounds.THRUST_MAX_N:g}].",
    )
    isp_s: Annotated[float, bounds.minimum(bounds.SPECIFIC_IMPULSE_S[0])] = Field(
        ...,
        gt=0,
        le=bounds.SPECIFIC_IMPULSE_S[1],
        description="Specific impulse, s, in "
        f"[{bounds.SPECIFIC_IMPULSE_S[0]:g}, {bounds.SPECIFIC_IMPULSE_S[1]:g}]: the mass flow "
        "is thrust / (isp_s * 9.80665) kg/s, with standard gravity 9.80665 m/s^2 (not the "
        "planet's g0).",
    )
    thrust_lag_s: float | None = Field(
        None,
        ge=0,
        le=bounds.TIME_MAX_S,
        description="Time constant tau of the engine's response, s: none or 0 = the thrust "
        "follows its command at once; > 0 (at least "
        f"{bounds.THRUST_LAG_MIN_S:g} s) = first-order lag dT/dt = (T_command - T) / tau, "
        "paper 004's K_T pi (T_command - T) / T_max with tau = T_max / (pi K_T).",
    )
    initial_thrust_n: float = Field(
        0.0,
        ge=0,
        le=bounds.THRUST_MAX_N,
        description="Thrust at the initial time, N, in [0, max_thrust_n]; matters only with a "
        "thrust lag (without one the thrust is the command).",
    )
    dry_mass_kg: (
        Annotated[float, Field(gt=0, le=bounds.MASS_KG[1]), bounds.minimum(bounds.MASS_KG[0])]
        | None
    ) = Field(
        None,
        description="Lowest mass the vehicle may reach (all propellant burnt), kg, below "
        "vehicle.mass_kg; none = the propellant is not limited.",
    )

    @field_validator("thrust_lag_s")
    @classmethod
    def _lag_not_tiny(cls, value: float | None) -> float | None:
        if value is not None and 0.0 < value < bounds.THRUST_LAG_MIN_S:
            raise PydanticCustomError(
                "below_minimum",
                "a thrust lag should be at least {low} s (give 0 for a thrust that follows its "
                "command at once)",
                {"low": f"{bounds.THRUST_LAG_MIN_S:g}"},
            )
        return value

    @model_validator(mode="after")
    def _initial_thrust(self) -> Propulsion:
        if self.initial_thrust_n > self.max_thrust_n:
            problem = FieldProblem(
                ("initial_thrust_n",),
                "thrust_limit",
                f"initial_thrust_n ({self.initial_thrust_n:g} N) exceeds max_thrust_n "
                f"({self.max_thrust_n:g} N)",
                self.initial_thrust_n,
            )
            raise_problems("Propulsion", [problem])
        return self

    @property
    def lagged(self) -> bool:
        """Whether the thrust lags its command (a positive ``thrust_lag_s``)."""
        return bool(self.thrust_lag_s)

    def mass_flow_kg_s(self, thrust_n: float) -> float:
        """Propellant burnt per second at ``thrust_n``, kg/s."""
        return thrust_n / (self.isp_s * STANDARD_GRAVITY_M_S2)
