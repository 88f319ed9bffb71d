"""A batch request: one base problem and how its children differ (a grid of parameter values, a
Monte Carlo dispersion, or a list of methods). Each child is an ordinary job."""

from __future__ import annotations

from typing import Any, Literal, Self

from pydantic import BaseModel, ConfigDict, Field, model_validator

BatchKind = Literal["grid", "monte_carlo", "methods", "footprint"]
KINDS: tuple[BatchKind, ...] = ("grid", "monte_carlo", "methods", "footprint")
"""The ways a batch's children differ from its base problem."""

POINTER_PATTERN = r"^(/([^/~]|~[01])*)+$"
"""A JSON pointer (RFC 6901) to a member of the problem document, not the whole document."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class GridParameter(_Strict):
    """One axis of a grid: the member at ``path`` takes each of ``values`` in turn."""

    path: str = Field(
        ...,
        pattern=POINTER_PATTERN,
        description="JSON pointer into the base problem document, e.g. "
        "/no_fly_zones/0/radius_deg or /path_constraints/heat_rate/max_W_m2.",
        examples=["/no_fly_zones/0/radius_deg"],
    )
    values: list[Any] = Field(..., min_length=1, description="The values the member takes.")


class GridSpec(_Strict):
    """Every combination of the parameters' values (the first parameter varies slowest)."""

    parameters: list[GridParameter] = Field(..., min_length=1, max_length=4)


class Dispersion(_Strict):
    """A random value for the number at ``path``: normal (mean, default the base value, and
    sigma) or uniform (low and high, or half_width around the base value)."""

    path: str = Field(..., pattern=POINTER_PATTERN, examples=["/initial_state/velocity_m_s"])
    distribution: Literal["normal", "uniform"]
    mean: float | None = Field(None, description="normal: the mean (default: the base value).")
    sigma: float | None = Field(None, gt=0, description="normal: the standard deviation.")
    low: float | None = Field(None, description="uniform: the lower end.")
    high: float | None = Field(None, description="uniform: the upper end.")
    half_width: float | None = Field(
        None, gt=0, description="uniform: base value +- half_width (instead of low and high)."
    )

    @model_validator(mode="after")
    def _complete(self) -> Self:
        if self.distribution == "normal":
            if self.sigma is None:
                raise ValueError("a normal dispersion needs sigma")
            if self.low is not None or self.high is not None or self.half_width is not None:
                raise ValueError("a normal dispersion takes mean and sigma only")
        else:
            ends = self.low is not None, self.high is not None
            if self.sigma is not None or self.mean is not None:
                raise ValueError("a uniform dispersion takes low and high, or half_width")
            if self.half_width is None and ends != (True, True):
                raise ValueError("a uniform dispersion needs low and high, or half_width")
            if self.half_width is not None and any(ends):
                raise ValueError("give low and high, or half_width, not both")
            if self.low is not None and self.high is not None and self.low >= self.high:
                raise ValueError(f"low {self.low} must be below high {self.high}")
        return self


class MonteCarloSpec(_Strict):
    """``samples`` children, each with every dispersion drawn once, from a generator seeded with
    ``seed``: the same request makes the same children."""

    samples: int = Field(..., ge=1)
    seed: int = Field(0, ge=0, description="Seed of the random generator (numpy PCG64).")
    dispersions: list[Dispersion] = Field(..., min_length=1)


Edge = Literal["max_final_latitude", "min_final_latitude"]
EDGES: tuple[Edge, ...] = ("max_final_latitude", "min_final_latitude")


class FootprintSpec(_Strict):
    """The reachable set of terminal points: at each final longitude, the largest and the
    smallest final latitude the vehicle can reach (the base's other terminal conditions and
    limits kept, its final latitude left free): two children per longitude."""

    longitudes_deg: list[float] = Field(
        ..., min_length=2, max_length=50, description="Final longitudes to sweep, deg."
    )
    extremes: list[Edge] = Field(
        default_factory=lambda: list(EDGES),
        min_length=1,
        description="Which edges of the footprint to find (default both).",
    )


class BatchRequest(_Strict):
    """A base problem (a problem document, or ``{"scenario", "overrides", "method"}``) and
    exactly one of ``grid``, ``monte_carlo``, ``methods`` or ``footprint``."""

    name: str | None = Field(None, max_length=200, description="A label for the batch.")
    base: dict[str, Any] = Field(
        ..., description="The problem every child starts from, as a job submission takes it."
    )
    grid: GridSpec | None = None
    monte_carlo: MonteCarloSpec | None = None
    methods: list[dict[str, Any]] | None = Field(
        None,
        min_length=1,
        description="Method comparison: each entry is a child's whole `method` object (name "
        "and options) on the same problem.",
    )
    footprint: FootprintSpec | None = None
    chain: bool = Field(
        False,
        description="Start each child from the answer of its nearest sibling finished by then "
        "(nearest in the parameters; same non-numeric parameters) instead of the method's own "
        "guess; the children still run in parallel.",
    )

    @model_validator(mode="after")
    def _one_kind(self) -> Self:
        given = [k for k in KINDS if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(
                "give exactly one of grid, monte_carlo, methods or footprint"
                + (f" (got {', '.join(given)})" if given else "")
            )
        return self

    @property
    def kind(self) -> BatchKind:
        """Which way the children differ."""
        return next(k for k in KINDS if getattr(self, k) is not None)
