"""Aerodynamic models of the vehicle: lift and drag coefficients as functions of the controls."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from app.schemas import bounds
from app.schemas.base import (
    FieldProblem,
    StrictModel,
    raise_problems,
    strictly_increasing,
    untagged_errors,
)
from app.schemas.limits import MAX_POLYNOMIAL_COEFFICIENTS, MAX_TABLE_POINTS

Coefficient = Annotated[
    float, Field(ge=-bounds.AERO_COEFFICIENT_MAX, le=bounds.AERO_COEFFICIENT_MAX)
]
"""A lift or drag coefficient, or a coefficient of their polynomials, bounded in magnitude."""
TableRow = Annotated[list[Coefficient], Field(max_length=MAX_TABLE_POINTS, fail_fast=True)]
"""One row of a coefficient table (one entry per Mach breakpoint)."""


class PolynomialAerodynamics(StrictModel):
    """CL and CD as polynomials: CL = sum_k c_k alpha_deg^k; CD in alpha_deg or in CL.

    The drag polar CD = 0.080505 - 0.03026 CL + 0.86495 CL^2 of the reusable launch vehicle
    used by energy-domain and time-domain SCP papers takes ``cd_argument = "cl"``.
    """

    model: Literal["polynomial"] = Field("polynomial", description="Aerodynamic model name.")
    cl_coefficients: list[Coefficient] = Field(
        ...,
        min_length=1,
        max_length=MAX_POLYNOMIAL_COEFFICIENTS,
        description="c_0..c_n of CL = sum_k c_k * alpha_deg^k (alpha in degrees), lowest first.",
    )
    cd_coefficients: list[Coefficient] = Field(
        ...,
        min_length=1,
        max_length=MAX_POLYNOMIAL_COEFFICIENTS,
        description="d_0..d_n of CD = sum_k d_k * x^k, lowest first; x per `cd_argument`.",
    )
    cd_argument: Literal["alpha", "cl"] = Field(
        ...,
        description='Argument x of the CD polynomial: "alpha" = angle of attack in degrees, '
        '"cl" = the lift coefficient.',
    )


class ParabolicPolarAerodynamics(StrictModel):
    """Parabolic drag polar, normalized lift lambda as control (CAV-H model of Yu, Zhao, Yang).

    CL = lambda * cl_star and CD = cd0 + k_induced * CL^2.
    """

    model: Literal["parabolic_polar"] = Field(
        "parabolic_polar", description="Aerodynamic model name."
    )
    cl_star: float = Field(
        ...,
        gt=0,
        le=bounds.AERO_COEFFICIENT_MAX,
        description="Lift coefficient at maximum L/D, > 0.",
    )
    cd0: float = Field(
        ..., gt=0, le=bounds.AERO_COEFFICIENT_MAX, description="Zero-lift drag coefficient, > 0."
    )
    k_induced: float = Field(
        ...,
        gt=0,
        le=bounds.AERO_COEFFICIENT_MAX,
        description="Induced-drag factor k of CD = cd0 + k CL^2.",
    )
    lambda_min: float = Field(
        0.0,
        ge=0,
        le=10,
        description="Lower bound of the normalized lift lambda = CL/cl_star, >= 0.",
    )
    lambda_max: float = Field(
        1.0, le=10, description="Upper bound of the normalized lift lambda, > lambda_min."
    )

    @model_validator(mode="after")
    def _lambda_order(self) -> ParabolicPolarAerodynamics:
        if not self.lambda_min < self.lambda_max:
            raise_problems(
                "ParabolicPolarAerodynamics",
                [
                    FieldProblem(
                        ("lambda_max",),
                        "lambda_order",
                        f"lambda_max ({self.lambda_max}) must exceed "
                        f"lambda_min ({self.lambda_min})",
                        self.lambda_max,
                    )
                ],
            )
        return self


class TableAerodynamics(StrictModel):
    """CL and CD tabulated on an (angle of attack, Mach) grid, rows along alpha."""

    model: Literal["table"] = Field("table", description="Aerodynamic model name.")
    alpha_deg: list[Annotated[float, Field(ge=-90, le=90)]] = Field(
        ...,
        min_length=2,
        max_length=MAX_TABLE_POINTS,
        fail_fast=True,
        description="Angle of attack breakpoints, deg, strictly increasing.",
    )
    mach: list[Annotated[float, Field(ge=0, le=bounds.MACH_MAX)]] = Field(
        ...,
        min_length=2,
        max_length=MAX_TABLE_POINTS,
        fail_fast=True,
        description="Mach number breakpoints, strictly increasing.",
    )
    cl: list[TableRow] = Field(
        ...,
        max_length=MAX_TABLE_POINTS,
        fail_fast=True,
        description="Lift coefficient, cl[i][j] at alpha_deg[i] and mach[j].",
    )
    cd: list[TableRow] = Field(
        ...,
        max_length=MAX_TABLE_POINTS,
        fail_fast=True,
        description="Drag coefficient, cd[i][j] at alpha_deg[i] and mach[j].",
    )
    interpolation: Literal["linear", "cubic"] = Field(
        "linear", description="Interpolation between breakpoints."
    )

    @model_validator(mode="after")
    def _grid(self) -> TableAerodynamics:
        problems: list[FieldProblem] = []
        for name in ("alpha_deg", "mach"):
            if not strictly_increasing(getattr(self, name)):
                problems.append(
                    FieldProblem((name,), "not_increasing", f"{name} must be strictly increasing")
                )
        rows, cols = len(self.alpha_deg), len(self.mach)
        for name in ("cl", "cd"):
            table: list[list[float]] = getattr(self, name)
            if len(table) != rows:
                problems.append(
                    FieldProblem(
                        (name,),
                        "table_shape",
                        f"{name} has {len(table)} rows; expected one per alpha_deg ({rows})",
                    )
                )
            for i, row in enumerate(table):
                if len(row) != cols:
                    problems.append(
                        FieldProblem(
                            (name, i),
                            "table_shape",
                            f"{name}[{i}] has {len(row)} entries; expected one per mach ({cols})",
                        )
                    )
        raise_problems("TableAerodynamics", problems)
        return self


Aerodynamics = Annotated[
    Annotated[
        PolynomialAerodynamics | ParabolicPolarAerodynamics | TableAerodynamics,
        Field(discriminator="model"),
    ],
    untagged_errors("model"),
]
"""The vehicle's aerodynamic model, selected by ``model``."""
