"""The entry vehicle: mass, reference area, aerodynamics, the angle-of-attack law and
propulsion."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from app.schemas import bounds
from app.schemas.aerodynamics import Aerodynamics
from app.schemas.base import (
    FieldProblem,
    StrictModel,
    raise_problems,
    strictly_increasing,
    untagged_errors,
)
from app.schemas.limits import MAX_TABLE_POINTS
from app.schemas.propulsion import Propulsion


class VelocityScheduleAngleOfAttack(StrictModel):
    """Angle of attack as a fixed function of speed, as in the energy- and time-domain SCP papers.

    alpha = alpha_max for V > V_break, else alpha_max - slope (V - V_break)^2 / scale^2 (deg).
    """

    mode: Literal["velocity_schedule"] = Field(
        "velocity_schedule", description="Angle-of-attack law name."
    )
    alpha_max_deg: float = Field(
        40.0, gt=-90, lt=90, description="Angle of attack above the break speed, deg."
    )
    velocity_break_m_s: float = Field(
        4570.0,
        gt=0,
        le=bounds.SPEED_MAX_M_S,
        description="Speed below which the angle of attack decreases, m/s.",
    )
    slope_coefficient: float = Field(
        0.20705,
        ge=0,
        le=bounds.AERO_COEFFICIENT_MAX,
        description="Slope of the quadratic decrease, deg per (V/scale)^2.",
    )
    velocity_scale_m_s: float = Field(
        340.0,
        gt=0,
        le=bounds.SPEED_MAX_M_S,
        description="Speed normalizing the quadratic decrease, m/s.",
    )


class TableAngleOfAttack(StrictModel):
    """Angle of attack interpolated linearly in a table over speed."""

    mode: Literal["table"] = Field("table", description="Angle-of-attack law name.")
    velocity_m_s: list[Annotated[float, Field(ge=0, le=bounds.SPEED_MAX_M_S)]] = Field(
        ...,
        min_length=2,
        max_length=MAX_TABLE_POINTS,
        fail_fast=True,
        description="Speed breakpoints, m/s, strictly increasing.",
    )
    alpha_deg: list[Annotated[float, Field(gt=-90, lt=90)]] = Field(
        ...,
        max_length=MAX_TABLE_POINTS,
        fail_fast=True,
        description="Angle of attack at each speed breakpoint, deg; same length.",
    )

    @model_validator(mode="after")
    def _table(self) -> TableAngleOfAttack:
        problems: list[FieldProblem] = []
        if not strictly_increasing(self.velocity_m_s):
            problems.append(
                FieldProblem(
                    ("velocity_m_s",), "not_increasing", "velocity_m_s must be strictly increasing"
                )
            )
        if len(self.alpha_deg) != len(self.velocity_m_s):
            problems.append(
                FieldProblem(
                    ("alpha_deg",),
                    "table_shape",
                    f"alpha_deg has {len(self.alpha_deg)} entries; "
                    f"expected one per velocity_m_s ({len(self.velocity_m_s)})",
                )
            )
        raise_problems("TableAngleOfAttack", problems)
        return self


class ConstantAngleOfAttack(StrictModel):
    """One angle of attack for the whole flight."""

    mode: Literal["constant"] = Field("constant", description="Angle-of-attack law name.")
    alpha_deg: float = Field(..., gt=-90, lt=90, description="Angle of attack, deg.")


class OptimizedAngleOfAttack(StrictModel):
    """Angle of attack as a state the optimizer shapes within bounds (rate-limited if asked)."""

    mode: Literal["optimized"] = Field("optimized", description="Angle-of-attack law name.")
    min_deg: float = Field(..., gt=-90, lt=90, description="Lower bound of angle of attack, deg.")
    max_deg: float = Field(
        ..., gt=-90, lt=90, description="Upper bound of angle of attack, deg; > min_deg."
    )
    rate_max_deg_s: float | None = Field(
        None,
        gt=0,
        le=bounds.ANGLE_RATE_MAX_DEG_S,
        description="Bound on |d alpha/dt|, deg/s; none means unbounded.",
    )
    initial_deg: float | None = Field(
        None,
        description="Angle of attack at the initial time, deg, within the bounds; none = free.",
    )

    @model_validator(mode="after")
    def _bounds(self) -> OptimizedAngleOfAttack:
        problems: list[FieldProblem] = []
        if not self.min_deg < self.max_deg:
            problems.append(
                FieldProblem(
                    ("max_deg",),
                    "bounds_order",
                    f"max_deg ({self.max_deg}) must exceed min_deg ({self.min_deg})",
                    self.max_deg,
                )
            )
        elif self.initial_deg is not None and not (
            self.min_deg <= self.initial_deg <= self.max_deg
        ):
            problems.append(
                FieldProblem(
                    ("initial_deg",),
                    "out_of_bounds",
                    f"initial_deg ({self.initial_deg}) is outside [{self.min_deg}, {self.max_deg}]",
                    self.initial_deg,
                )
            )
        raise_problems("OptimizedAngleOfAttack", problems)
        return self


AngleOfAttack = Annotated[
    Annotated[
        VelocityScheduleAngleOfAttack
        | TableAngleOfAttack
        | ConstantAngleOfAttack
        | OptimizedAngleOfAttack,
        Field(discriminator="mode"),
    ],
    untagged_errors("mode"),
]
"""How the angle of attack is determined, selected by ``mode``."""


class Vehicle(StrictModel):
    """Mass and aerodynamic description of the entry vehicle."""

    mass_kg: Annotated[float, bounds.minimum(bounds.MASS_KG[0])] = Field(
        ...,
        gt=0,
        le=bounds.MASS_KG[1],
        description=f"Vehicle mass at the initial time, kg, in [{bounds.MASS_KG[0]:g}, "
        f"{bounds.MASS_KG[1]:g}]; constant during entry unless propulsion is given (then it "
        "falls as propellant burns).",
    )
    reference_area_m2: Annotated[float, bounds.minimum(bounds.REFERENCE_AREA_M2[0])] = Field(
        ...,
        gt=0,
        le=bounds.REFERENCE_AREA_M2[1],
        description="Aerodynamic reference area, m^2, in "
        f"[{bounds.REFERENCE_AREA_M2[0]:g}, {bounds.REFERENCE_AREA_M2[1]:g}].",
    )
    aerodynamics: Aerodynamics = Field(..., description="Lift and drag coefficient model.")
    angle_of_attack: AngleOfAttack | None = Field(
        None,
        description="Angle-of-attack law: schedule, table, constant or optimized. Required with "
        "polynomial or tabulated aerodynamics; left out with a parabolic polar, whose lift is "
        "set by the normalized lift lambda instead.",
    )
    propulsion: Propulsion | None = Field(
        None,
        description="Rocket engine (thrust, specific impulse, thrust lag, dry mass); none = an "
        "unpowered glider of constant mass.",
    )

    @model_validator(mode="after")
    def _lift_control(self) -> Vehicle:
        """A polar vehicle's lift control is lambda, every other model's the angle of attack."""
        polar = self.aerodynamics.model == "parabolic_polar"
        if polar and self.angle_of_attack is not None:
            problem = FieldProblem(
                ("angle_of_attack",),
                "not_applicable",
                "a parabolic polar has no angle of attack (its lift is set by the normalized "
                "lift lambda within lambda_min..lambda_max); leave angle_of_attack out",
            )
            raise_problems("Vehicle", [problem])
        if not polar and self.angle_of_attack is None:
            problem = FieldProblem(
                ("angle_of_attack",),
                "missing",
                f"{self.aerodynamics.model} aerodynamics need an angle-of-attack law "
                "(velocity_schedule, table, constant or optimized)",
            )
            raise_problems("Vehicle", [problem])
        return self

    @model_validator(mode="after")
    def _dry_mass(self) -> Vehicle:
        """The dry mass is what remains when the propellant is gone: below the initial mass."""
        dry = self.propulsion.dry_mass_kg if self.propulsion is not None else None
        if dry is not None and dry >= self.mass_kg:
            problem = FieldProblem(
                ("propulsion", "dry_mass_kg"),
                "dry_mass_order",
                f"dry_mass_kg ({dry:g} kg) must be below the vehicle's initial mass_kg "
                f"({self.mass_kg:g} kg)",
                dry,
            )
            raise_problems("Vehicle", [problem])
        return self
