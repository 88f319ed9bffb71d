"""Path constraints (heating, dynamic pressure, load factor) and control limits."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field, ValidationInfo, field_validator
from pydantic_core import PydanticCustomError

from app.schemas import bounds
from app.schemas.base import StrictModel


class HeatRateLimit(StrictModel):
    """Stagnation-point heat rate bound: k_q rho^n V^m qa(alpha) <= max_W_m2 (SI units).

    The alpha factor qa = c0 + c1 alpha + c2 alpha^2 + c3 alpha^3 (alpha in degrees) is the
    Space Shuttle heating correction used by Wang, Leonard, Savvaris and Tsourdos.
    """

    max_W_m2: float = Field(
        ...,
        gt=0,
        le=bounds.HEAT_RATE_MAX_W_M2,
        description="Largest admissible heat rate, W/m^2.",
    )
    k_q: float = Field(
        ...,
        gt=0,
        le=bounds.HEATING_CONSTANT_MAX,
        description="Heating constant in SI: Qdot[W/m^2] = k_q * rho^density_exponent * "
        "V^velocity_exponent * alpha_factor, rho in kg/m^3, V in m/s.",
    )
    velocity_exponent: float = Field(
        3.15, gt=0, le=bounds.EXPONENT_MAX, description="Exponent m of the speed V."
    )
    density_exponent: float = Field(
        0.5, gt=0, le=bounds.EXPONENT_MAX, description="Exponent n of the density rho."
    )
    alpha_polynomial: (
        list[
            Annotated[float, Field(ge=-bounds.AERO_COEFFICIENT_MAX, le=bounds.AERO_COEFFICIENT_MAX)]
        ]
        | None
    ) = Field(
        None,
        min_length=1,
        max_length=4,
        description="c0..c3 of the factor qa = sum_k c_k alpha_deg^k; none means qa = 1.",
    )


class DynamicPressureLimit(StrictModel):
    """Dynamic pressure bound: rho V^2 / 2 <= max_Pa."""

    max_Pa: float = Field(
        ...,
        gt=0,
        le=bounds.DYNAMIC_PRESSURE_MAX_PA,
        description="Largest admissible dynamic pressure, Pa.",
    )


class LoadFactorLimit(StrictModel):
    """Aerodynamic load factor bound: sqrt(L^2 + D^2) / (m g0) <= max_g."""

    max_g: float = Field(
        ...,
        gt=0,
        le=bounds.LOAD_FACTOR_MAX_G,
        description="Largest admissible load factor, in units of g0 (surface gravity).",
    )


class PathConstraints(StrictModel):
    """Inequality constraints along the whole trajectory; each is off when absent."""

    heat_rate: HeatRateLimit | None = Field(None, description="Heat rate limit; none = off.")
    dynamic_pressure: DynamicPressureLimit | None = Field(
        None, description="Dynamic pressure limit; none = off."
    )
    load_factor: LoadFactorLimit | None = Field(None, description="Load factor limit; none = off.")


class ControlLimits(StrictModel):
    """Bounds on the bank angle, and on bank and angle-of-attack rates when they are states."""

    bank_max_deg: float = Field(
        80.0,
        description="Upper bound on the bank angle, deg, in (0, 90] (lift never points down); "
        "also the bound on |bank| unless bank_min_deg is given.",
    )
    bank_min_deg: float | None = Field(
        None,
        description="Lower bound on the bank angle, deg, in [-90, bank_max_deg); none means "
        "-bank_max_deg (a symmetric range). An asymmetric range such as Betts' [-89, 1] for "
        "the Space Shuttle's maximum crossrange turns the vehicle one way only.",
    )
    bank_rate_max_deg_s: float | None = Field(
        None,
        gt=0,
        le=bounds.ANGLE_RATE_MAX_DEG_S,
        description="Bound on |d bank/dt|, deg/s; none means unbounded.",
    )
    alpha_rate_max_deg_s: float | None = Field(
        None,
        gt=0,
        le=bounds.ANGLE_RATE_MAX_DEG_S,
        description="Bound on |d alpha/dt|, deg/s; none means unbounded.",
    )

    @field_validator("bank_max_deg")
    @classmethod
    def _bank_range(cls, value: float) -> float:
        if not 0.0 < value <= 90.0:
            raise PydanticCustomError(
                "bank_limit",
                "bank limit must be in (0, 90] degrees, got {value}",
                {"value": value},
            )
        return value

    @field_validator("bank_min_deg")
    @classmethod
    def _bank_min_range(cls, value: float | None, info: ValidationInfo) -> float | None:
        if value is None:
            return value
        if not -90.0 <= value < 90.0:
            raise PydanticCustomError(
                "bank_limit",
                "bank lower bound must be in [-90, 90) degrees, got {value}",
                {"value": value},
            )
        high = info.data.get("bank_max_deg")  # absent when bank_max_deg itself was refused
        if high is not None and value >= high:
            raise PydanticCustomError(
                "bank_limit",
                "bank_min_deg ({low}) must be below bank_max_deg ({high})",
                {"low": value, "high": high},
            )
        return value

    @property
    def bank_lower_deg(self) -> float:
        """The lower bound on the bank angle, deg (-bank_max_deg when none is given)."""
        return -self.bank_max_deg if self.bank_min_deg is None else self.bank_min_deg
