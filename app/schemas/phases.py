"""Phases of a flight: linked legs, each with its own duration, end conditions, control bounds,
thrust limit and path constraints (paper 004's skip entry: a descent, then a powered exit)."""

from __future__ import annotations

from pydantic import Field, model_validator

from app.schemas import bounds
from app.schemas.base import FieldProblem, StrictModel, Text, raise_problems
from app.schemas.constraints import PathConstraints
from app.schemas.terminal import TerminalConditions


class DurationBounds(StrictModel):
    """How long a phase may last, s: min_s <= duration <= max_s."""

    min_s: float = Field(
        ...,
        gt=0,
        le=bounds.TIME_MAX_S,
        description=f"Shortest duration of the phase, s, in (0, {bounds.TIME_MAX_S:g}].",
    )
    max_s: float = Field(
        ...,
        gt=0,
        le=bounds.TIME_MAX_S,
        description=f"Longest duration of the phase, s, > min_s and at most {bounds.TIME_MAX_S:g}.",
    )

    @model_validator(mode="after")
    def _ordered(self) -> DurationBounds:
        if not self.min_s < self.max_s:
            problem = FieldProblem(
                ("max_s",),
                "bounds_order",
                f"max_s ({self.max_s:g} s) must exceed min_s ({self.min_s:g} s)",
                self.max_s,
            )
            raise_problems("DurationBounds", [problem])
        return self


class AngleBounds(StrictModel):
    """Bounds on the angle of attack during a phase, deg: min_deg <= alpha <= max_deg."""

    min_deg: float = Field(
        ..., ge=-90, le=90, description="Lower bound of the angle of attack, deg, in [-90, 90]."
    )
    max_deg: float = Field(
        ...,
        ge=-90,
        le=90,
        description="Upper bound of the angle of attack, deg, in [-90, 90]; > min_deg.",
    )

    @model_validator(mode="after")
    def _ordered(self) -> AngleBounds:
        if not self.min_deg < self.max_deg:
            problem = FieldProblem(
                ("max_deg",),
                "bounds_order",
                f"max_deg ({self.max_deg:g}) must exceed min_deg ({self.min_deg:g})",
                self.max_deg,
            )
            raise_problems("AngleBounds", [problem])
        return self


class Phase(StrictModel):
    """One leg of the flight. Phases follow each other in list order: each starts where and when
    the previous one ends (state, mass and thrust continuous), the first at the initial state;
    the last one's ``end`` holds the final conditions. What a phase leaves out is the document's.
    """

    name: Text = Field(
        ...,
        min_length=1,
        max_length=64,
        description="Name of the phase, 1 to 64 characters, unique among the phases.",
    )
    duration_s: DurationBounds = Field(
        ..., description="Bounds on how long the phase lasts, s (its duration is optimized)."
    )
    end: TerminalConditions = Field(
        default_factory=TerminalConditions,
        description="Conditions on the state at the phase's end (fixed, range, free or soft per "
        "component, as terminal conditions); every component defaults to free.",
    )
    angle_of_attack_deg: AngleBounds | None = Field(
        None,
        description="Angle-of-attack bounds in this phase, deg; none = the bounds of the "
        "vehicle's optimized angle of attack.",
    )
    bank_min_deg: float | None = Field(
        None,
        ge=-90,
        le=90,
        description="Lower bound on the bank angle in this phase, deg, in [-90, 90]; none = "
        "the lower bound of control_limits.",
    )
    bank_max_deg: float | None = Field(
        None,
        ge=-90,
        le=90,
        description="Upper bound on the bank angle in this phase, deg, in [-90, 90], above "
        "the lower bound; none = control_limits.bank_max_deg.",
    )
    thrust_max_n: float | None = Field(
        None,
        ge=0,
        le=bounds.THRUST_MAX_N,
        description="Largest commanded thrust in this phase, N, at most "
        "vehicle.propulsion.max_thrust_n; 0 = a coast (engine off); none = "
        "vehicle.propulsion.max_thrust_n (no thrust without propulsion).",
    )
    path_constraints: PathConstraints | None = Field(
        None,
        description="Path constraints in this phase (replacing the document's as a whole); "
        "none = the document's path_constraints.",
    )

    @model_validator(mode="after")
    def _bank_order(self) -> Phase:
        low, high = self.bank_min_deg, self.bank_max_deg
        if low is not None and high is not None and not low < high:
            problem = FieldProblem(
                ("bank_min_deg",),
                "bank_limit",
                f"bank_min_deg ({low:g}) must be below bank_max_deg ({high:g})",
                low,
            )
            raise_problems("Phase", [problem])
        return self

    def bank_range_deg(self, default_low: float, default_high: float) -> tuple[float, float]:
        """The phase's bank range, deg: its own bounds, the given defaults where it has none."""
        low = default_low if self.bank_min_deg is None else self.bank_min_deg
        high = default_high if self.bank_max_deg is None else self.bank_max_deg
        return low, high
