"""The planet: spherical shape, gravity, rotation and atmosphere model."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, model_validator

from app.schemas import bounds
from app.schemas.base import FieldProblem, StrictModel, raise_problems, untagged_errors


class ExponentialAtmosphere(StrictModel):
    """Isothermal exponential density rho = rho0 exp(-h / H), with a constant speed of sound."""

    model: Literal["exponential"] = Field("exponential", description="Atmosphere model name.")
    density_sea_level_kg_m3: float = Field(
        1.225,
        gt=0,
        le=bounds.DENSITY_MAX_KG_M3,
        description="Density rho0 at zero altitude, kg/m^3.",
    )
    scale_height_m: Annotated[float, bounds.minimum(bounds.SCALE_HEIGHT_M[0])] = Field(
        ...,
        gt=0,
        le=bounds.SCALE_HEIGHT_M[1],
        description="Density scale height H, m.",
    )
    speed_of_sound_m_s: Annotated[float, bounds.minimum(bounds.SPEED_OF_SOUND_M_S[0])] = Field(
        295.07,
        gt=0,
        le=bounds.SPEED_OF_SOUND_M_S[1],
        description="Constant speed of sound, m/s; the model has no temperature, so this is "
        "used only to form the Mach number for Mach-dependent aerodynamics.",
    )


class US76Atmosphere(StrictModel):
    """The U.S. Standard Atmosphere 1976 (density and speed of sound from tables; no parameters)."""

    model: Literal["us76"] = Field("us76", description="Atmosphere model name.")


Atmosphere = Annotated[
    Annotated[ExponentialAtmosphere | US76Atmosphere, Field(discriminator="model")],
    untagged_errors("model"),
]
"""The atmosphere model, selected by ``model``."""


class Planet(StrictModel):
    """Spherical planet with inverse-square gravity.

    Exactly one of ``g0_m_s2`` and ``mu_m3_s2`` is given (``g0_m_s2`` defaults to 9.81).
    """

    radius_m: Annotated[float, bounds.minimum(bounds.RADIUS_M[0])] = Field(
        6378140.0,
        gt=0,
        le=bounds.RADIUS_M[1],
        description="Reference sphere radius R0, m.",
    )
    g0_m_s2: (
        Annotated[
            float,
            Field(gt=0, le=bounds.SURFACE_GRAVITY_M_S2[1]),
            bounds.minimum(bounds.SURFACE_GRAVITY_M_S2[0]),
        ]
        | None
    ) = Field(
        9.81,
        description="Gravitational acceleration at radius R0, m/s^2. Defaults to 9.81 unless "
        "mu_m3_s2 is given; giving both is an error.",
    )
    mu_m3_s2: float | None = Field(
        None,
        gt=0,
        le=bounds.MU_MAX_M3_S2,
        description="Gravitational parameter mu, m^3/s^2; then g0 = mu / R0^2, which must lie "
        f"in [{bounds.SURFACE_GRAVITY_M_S2[0]:g}, {bounds.SURFACE_GRAVITY_M_S2[1]:g}] m/s^2.",
    )
    model: Literal["spherical", "flat"] = Field(
        "spherical",
        description='Equations of motion: "spherical", the point-mass equations over the sphere '
        '(every method); "flat", the flat-Earth small flight-path-angle model of paper 001 '
        "eq. 1 (Jorris & Cobb): longitude and latitude are flat map coordinates in radians of "
        "the planet's radius, no gravity in the speed equation, no rotation; distances to "
        "no-fly zones (which must use the lat_lon metric) and waypoints are map distances. "
        "Only cheb-scvx flies it.",
    )
    rotation: bool = Field(False, description="Whether the planet's rotation enters the dynamics.")
    rotation_rate_rad_s: float = Field(
        7.292115e-5,
        ge=0,
        le=bounds.ROTATION_RATE_MAX_RAD_S,
        description="Rotation rate, rad/s (used when `rotation` is true).",
    )
    atmosphere: Atmosphere = Field(..., description="Atmosphere model.")

    @model_validator(mode="before")
    @classmethod
    def _mu_replaces_default_g0(cls, data: Any) -> Any:
        """Giving ``mu_m3_s2`` alone drops the default ``g0_m_s2``."""
        if isinstance(data, dict) and data.get("mu_m3_s2") is not None and "g0_m_s2" not in data:
            return {**data, "g0_m_s2": None}
        return data

    @model_validator(mode="after")
    def _one_gravity(self) -> Planet:
        if (self.g0_m_s2 is None) == (self.mu_m3_s2 is None):
            raise_problems(
                "Planet",
                [
                    FieldProblem(
                        ("g0_m_s2",),
                        "gravity_spec",
                        "exactly one of g0_m_s2 and mu_m3_s2 must be given",
                        self.g0_m_s2,
                    )
                ],
            )
        low, high = bounds.SURFACE_GRAVITY_M_S2
        if self.mu_m3_s2 is not None and not low <= self.surface_gravity_m_s2 <= high:
            raise_problems(
                "Planet",
                [
                    FieldProblem(
                        ("mu_m3_s2",),
                        "surface_gravity_range",
                        f"mu / R0^2 = {self.surface_gravity_m_s2:g} m/s^2 is outside "
                        f"[{low:g}, {high:g}] m/s^2",
                        self.mu_m3_s2,
                    )
                ],
            )
        return self

    @model_validator(mode="after")
    def _flat_without_rotation(self) -> Planet:
        if self.model == "flat" and self.rotation:
            raise_problems(
                "Planet",
                [
                    FieldProblem(
                        ("rotation",),
                        "not_applicable",
                        "the flat-Earth model has no rotation; set rotation false",
                        self.rotation,
                    )
                ],
            )
        return self

    @property
    def surface_gravity_m_s2(self) -> float:
        """Gravitational acceleration at radius R0, m/s^2 (g0, or mu / R0^2)."""
        if self.g0_m_s2 is not None:
            return self.g0_m_s2
        assert self.mu_m3_s2 is not None  # guaranteed by validation
        return self.mu_m3_s2 / self.radius_m**2
