"""Terminal conditions: each final state component is fixed, bounded, free, or a soft target."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, Field, model_validator

from app.schemas import bounds
from app.schemas.base import FieldProblem, StrictModel, raise_problems, untagged_errors


class FixedSpec(StrictModel):
    """The component must equal ``value`` at the final time (a hard equality constraint)."""

    kind: Literal["fixed"] = Field("fixed", description="Spec kind: a hard equality.")
    value: float = Field(..., description="Required final value, in the unit of the field.")

    def target(self) -> float | None:
        """The required value."""
        return self.value

    def contains(self, x: float, tol: float = 0.0) -> bool:
        """Whether ``x`` equals the required value within ``tol``."""
        return abs(x - self.value) <= tol


class RangeSpec(StrictModel):
    """The component must lie in ``[lo, hi]`` at the final time (hard bounds)."""

    kind: Literal["range"] = Field("range", description="Spec kind: hard bounds.")
    lo: float = Field(..., description="Lower bound, in the unit of the field.")
    hi: float = Field(..., description="Upper bound, in the unit of the field; lo <= hi.")

    @model_validator(mode="after")
    def _ordered(self) -> RangeSpec:
        if self.lo > self.hi:
            raise_problems(
                "RangeSpec",
                [FieldProblem((), "range_order", f"lo > hi ({self.lo} > {self.hi})", self.lo)],
            )
        return self

    def target(self) -> float | None:
        """The midpoint of the range."""
        return 0.5 * (self.lo + self.hi)

    def contains(self, x: float, tol: float = 0.0) -> bool:
        """Whether ``x`` lies in the range widened by ``tol`` on each side."""
        return self.lo - tol <= x <= self.hi + tol


class FreeSpec(StrictModel):
    """The component is not constrained at the final time."""

    kind: Literal["free"] = Field("free", description="Spec kind: unconstrained.")

    def target(self) -> float | None:
        """No target: always ``None``."""
        return None

    def contains(self, x: float, tol: float = 0.0) -> bool:
        """Every value is admissible."""
        return True


class SoftSpec(StrictModel):
    """A target whose miss ``|x_f - value|`` is penalized with ``weight`` (no hard constraint)."""

    kind: Literal["soft"] = Field("soft", description="Spec kind: a penalized target.")
    value: float = Field(..., description="Target final value, in the unit of the field.")
    weight: float = Field(
        ...,
        gt=0,
        le=bounds.WEIGHT_MAX,
        description="Penalty weight on the miss (nondimensional), > 0.",
    )

    def target(self) -> float | None:
        """The target value."""
        return self.value

    def contains(self, x: float, tol: float = 0.0) -> bool:
        """Whether ``x`` hits the target within ``tol`` (the miss is penalized, not forbidden)."""
        return abs(x - self.value) <= tol


def _number_as_fixed(value: Any) -> Any:
    """Read a plain number as shorthand for ``{"kind": "fixed", "value": number}``."""
    if isinstance(value, int | float) and not isinstance(value, bool):
        return {"kind": "fixed", "value": value}
    return value


TerminalSpec = Annotated[
    Annotated[FixedSpec | RangeSpec | FreeSpec | SoftSpec, Field(discriminator="kind")],
    untagged_errors("kind"),
    BeforeValidator(_number_as_fixed),
]
"""One terminal state component; a plain JSON number means ``{"kind": "fixed", "value": x}``."""

AnySpec = FixedSpec | RangeSpec | FreeSpec | SoftSpec

# Closed admissible interval of every value a spec of each field may name.
_DOMAINS: dict[str, tuple[float, float]] = {
    "altitude_m": (0.0, bounds.ALTITUDE_MAX_M),
    "longitude_deg": (-360.0, 360.0),
    "latitude_deg": (-90.0, 90.0),
    "velocity_m_s": (0.0, bounds.SPEED_MAX_M_S),
    "flight_path_angle_deg": (-90.0, 90.0),
    "heading_deg": (-360.0, 360.0),
}


def _spec_values(spec: AnySpec) -> list[tuple[str, float]]:
    """The named numbers a spec carries (value, or lo and hi)."""
    if isinstance(spec, FixedSpec | SoftSpec):
        return [("value", spec.value)]
    if isinstance(spec, RangeSpec):
        return [("lo", spec.lo), ("hi", spec.hi)]
    return []


def _spec_field(description: str) -> Any:
    return Field(default_factory=FreeSpec, description=description)


class TerminalConditions(StrictModel):
    """Conditions on the state at the final time; every component defaults to free."""

    altitude_m: TerminalSpec = _spec_field("Final altitude above the reference sphere, m.")
    longitude_deg: TerminalSpec = _spec_field("Final longitude, deg.")
    latitude_deg: TerminalSpec = _spec_field("Final geocentric latitude, deg.")
    velocity_m_s: TerminalSpec = _spec_field("Final planet-relative speed, m/s.")
    flight_path_angle_deg: TerminalSpec = _spec_field("Final flight path angle, deg.")
    heading_deg: TerminalSpec = _spec_field("Final heading angle (from north, clockwise), deg.")

    @model_validator(mode="after")
    def _in_domain(self) -> TerminalConditions:
        problems: list[FieldProblem] = []
        for name, (low, high) in _DOMAINS.items():
            spec: AnySpec = getattr(self, name)
            for key, x in _spec_values(spec):
                if not low <= x <= high:
                    problems.append(
                        FieldProblem(
                            (name, key),
                            "terminal_out_of_domain",
                            f"{x} is outside the admissible interval [{low}, {high}] of {name}",
                            x,
                        )
                    )
        raise_problems("TerminalConditions", problems)
        return self

    def specs(self) -> dict[str, AnySpec]:
        """Every component's spec by field name."""
        return {name: getattr(self, name) for name in _DOMAINS}
