"""Initial state, final-time specification and the energy interval of the entry problem."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from app.schemas import bounds
from app.schemas.base import FieldProblem, StrictModel, raise_problems, untagged_errors


class InitialState(StrictModel):
    """The fully specified state at the entry interface (spherical, planet-relative)."""

    altitude_m: float = Field(
        ...,
        gt=0,
        le=bounds.ALTITUDE_MAX_M,
        description=f"Altitude above the reference sphere, m, in (0, {bounds.ALTITUDE_MAX_M:g}].",
    )
    longitude_deg: float = Field(..., ge=-180, le=180, description="Longitude, deg, [-180, 180].")
    latitude_deg: float = Field(
        ...,
        gt=-90,
        lt=90,
        description="Geocentric latitude, deg, strictly inside (-90, 90): the spherical "
        "equations of motion are singular at the poles.",
    )
    velocity_m_s: float = Field(
        ...,
        gt=0,
        le=bounds.SPEED_MAX_M_S,
        description=f"Planet-relative speed, m/s, in (0, {bounds.SPEED_MAX_M_S:g}].",
    )
    flight_path_angle_deg: float = Field(
        ..., gt=-90, lt=90, description="Flight path angle, deg, (-90, 90); negative descends."
    )
    heading_deg: float = Field(
        ..., ge=-360, le=360, description="Heading angle from north, clockwise, deg."
    )
    time_s: float = Field(
        0.0,
        ge=-bounds.TIME_MAX_S,
        le=bounds.TIME_MAX_S,
        description="Time at the initial state, s.",
    )
    bank_deg: float | None = Field(
        None, ge=-180, le=180, description="Initial bank angle, deg, when bank is a state."
    )
    alpha_deg: float | None = Field(
        None,
        gt=-90,
        lt=90,
        description="Initial angle of attack, deg, when angle of attack is a state.",
    )


class FreeFinalTime(StrictModel):
    """The final time is a decision variable, optionally bounded above."""

    kind: Literal["free"] = Field("free", description="Final-time kind.")
    max_s: float | None = Field(
        None,
        gt=0,
        le=bounds.TIME_MAX_S,
        description="Latest admissible final time, s; none means unbounded.",
    )


class FixedFinalTime(StrictModel):
    """The flight ends at the given time."""

    kind: Literal["fixed"] = Field("fixed", description="Final-time kind.")
    value_s: float = Field(
        ...,
        gt=0,
        le=bounds.TIME_MAX_S,
        description="Final time, s; exceeds the initial time.",
    )


FinalTime = Annotated[
    Annotated[FreeFinalTime | FixedFinalTime, Field(discriminator="kind")],
    untagged_errors("kind"),
]
"""Whether the final time is free (default) or fixed, selected by ``kind``."""


class EnergyBounds(StrictModel):
    """Interval of the energy-like variable e = R0/r - V^2/(2 g0 R0), nondimensional.

    Defined in Jung, Kim, Choi and Lee, "Entry vehicle trajectory optimization using convex
    programming and post-correction technique", eq. (7); energy-domain methods integrate over e,
    which increases monotonically during entry over a non-rotating planet.
    A missing bound is derived from the initial state or the terminal altitude and speed.
    """

    initial: float | None = Field(
        None,
        ge=-bounds.ENERGY_MAX,
        le=bounds.ENERGY_MAX,
        description="Nondimensional energy at the initial state; none = derived.",
    )
    final: float | None = Field(
        None,
        ge=-bounds.ENERGY_MAX,
        le=bounds.ENERGY_MAX,
        description="Nondimensional energy at the final state; none = derived.",
    )

    @model_validator(mode="after")
    def _ordered(self) -> EnergyBounds:
        if self.initial is not None and self.final is not None and self.initial >= self.final:
            raise_problems(
                "EnergyBounds",
                [
                    FieldProblem(
                        ("final",),
                        "energy_order",
                        f"energies out of order: initial ({self.initial}) must be below final "
                        f"({self.final}) since energy increases during entry",
                        self.final,
                    )
                ],
            )
        return self
