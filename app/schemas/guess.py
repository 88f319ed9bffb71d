"""An initial guess: start a method from an earlier answer instead of its own guess."""

from __future__ import annotations

from typing import Any, Literal, Self

from pydantic import Field, model_validator

from app.schemas.base import FieldProblem, StrictModel, raise_problems
from app.schemas.methods.common import BoundedOptions

MAX_GUESS_POINTS = 20_000
"""Points a guess trajectory may have (a 1 000-node result's propagated flight has ~20 000)."""

GUESS_COLUMNS = (
    "time_s",
    "altitude_m",
    "longitude_deg",
    "latitude_deg",
    "velocity_m_s",
    "flight_path_angle_deg",
    "heading_deg",
    "bank_deg",
)
"""The columns of a guess trajectory (those of a result's trajectory that a start needs)."""
OPTIONAL_GUESS_COLUMNS = ("alpha_deg",)
"""Columns a guess may have (an optimized angle of attack starts from it)."""


def _column(description: str) -> list[float]:
    column: list[float] = Field(
        ..., min_length=2, max_length=MAX_GUESS_POINTS, description=description
    )
    return column


class GuessTrajectory(StrictModel):
    """A trajectory as columns, one value per point, in the units of their names (the columns
    of a result's ``trajectory``); time increasing. A method interpolates it onto its own grid
    (linearly, in time scaled to its final time, or in energy)."""

    time_s: list[float] = _column("Time of each point, s, strictly increasing.")
    altitude_m: list[float] = _column("Altitude, m.")
    longitude_deg: list[float] = _column("Longitude, deg.")
    latitude_deg: list[float] = _column("Latitude, deg.")
    velocity_m_s: list[float] = _column("Relative speed, m/s (positive).")
    flight_path_angle_deg: list[float] = _column("Flight-path angle, deg.")
    heading_deg: list[float] = _column("Heading, deg.")
    bank_deg: list[float] = _column("Bank angle, deg.")
    alpha_deg: list[float] | None = Field(
        None,
        min_length=2,
        max_length=MAX_GUESS_POINTS,
        description="Angle of attack, deg (optional: a method that optimizes it starts from "
        "it, else from its own initial value).",
    )

    @model_validator(mode="after")
    def _consistent(self) -> Self:
        problems: list[FieldProblem] = []
        count = len(self.time_s)
        for name in (*GUESS_COLUMNS[1:], *OPTIONAL_GUESS_COLUMNS):
            if getattr(self, name) is not None and len(getattr(self, name)) != count:
                problems.append(
                    FieldProblem(
                        (name,),
                        "length_mismatch",
                        f"has {len(getattr(self, name))} values, time_s has {count}",
                    )
                )
        steps = [b - a for a, b in zip(self.time_s, self.time_s[1:], strict=False)]
        if any(step <= 0 for step in steps):
            at = next(i for i, step in enumerate(steps) if step <= 0) + 1
            problems.append(
                FieldProblem(("time_s", at), "not_increasing", "must be strictly increasing")
            )
        if any(v <= 0 for v in self.velocity_m_s):
            at = next(i for i, v in enumerate(self.velocity_m_s) if v <= 0)
            problems.append(FieldProblem(("velocity_m_s", at), "not_positive", "must be > 0"))
        raise_problems("initial_guess.trajectory", problems)
        return self


class GlobalGuessOptions(BoundedOptions):
    """A global search for a start (paper 004 sec. 2.2-2.4): each phase's angle of attack and
    bank at a few knots, its duration and, when it may thrust, a full-thrust burn's start and
    length, scored by the propagated end-condition errors."""

    algorithm: Literal["ga", "pso"] = Field(
        "ga", description="Genetic algorithm (ga) or particle swarm (pso), both from pymoo."
    )
    seed: int = Field(1, ge=0, le=2**31 - 1, description="Random seed: same seed, same guess.")
    population: int = Field(
        40, ge=4, le=1000, description="Individuals (ga) or particles (pso) per generation."
    )
    max_evaluations: int = Field(
        4000, ge=10, le=1_000_000, description="Most candidate trajectories propagated."
    )
    time_limit_s: float = Field(
        60.0,
        gt=0,
        le=3600,
        description="Most CPU seconds of the solving process the search may take (a wall-clock "
        "safety of 4 x as many seconds also ends it).",
    )
    knots: int = Field(
        3, ge=1, le=8, description="Knots of alpha and bank per phase (linear between them)."
    )


class InitialGuess(StrictModel):
    """Where a method starts: ``from_job`` (one of the caller's finished jobs with a
    trajectory; the service copies its trajectory here), an explicit ``trajectory``, or
    ``kind: "global"``: a GA/PSO search of the controls (``search``) whose best flight is the
    start, for a problem far from the method's own guesses."""

    kind: Literal["global"] | None = Field(
        None,
        description="global: start from the best flight of a GA/PSO search of the controls "
        "(scored by its terminal misses and path-limit excess); omitted: from_job or trajectory.",
    )
    search: GlobalGuessOptions | None = Field(
        None, description='The global search (kind "global"; its defaults when omitted).'
    )

    from_job: str | None = Field(
        None,
        pattern=r"^[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}$",
        description="Id of one of your finished jobs whose trajectory to start from.",
    )
    trajectory: GuessTrajectory | None = Field(
        None, description="The trajectory to start from (filled in by the service for from_job)."
    )

    @model_validator(mode="after")
    def _something(self) -> Self:
        problems: list[FieldProblem] = []
        if self.kind == "global":
            for name in ("from_job", "trajectory"):
                if getattr(self, name) is not None:
                    problems.append(
                        FieldProblem(
                            (name,), "conflicting_start", 'not with kind "global" (one start)'
                        )
                    )
        elif self.search is not None:
            problems.append(
                FieldProblem(("search",), "search_without_global", 'needs kind "global"')
            )
        elif self.from_job is None and self.trajectory is None:
            problems.append(
                FieldProblem((), "missing", 'give from_job, trajectory or kind "global"')
            )
        raise_problems("initial_guess", problems)
        return self


def guess_columns(trajectory: dict[str, Any]) -> dict[str, list[float]] | None:
    """The columns of a result's trajectory a guess takes (the optional ones when complete);
    None when a needed one is missing or holds a null (a non-finite value)."""

    def complete(values: Any) -> bool:
        return isinstance(values, list) and None not in values

    columns = {name: trajectory.get(name) for name in GUESS_COLUMNS}
    if not all(complete(v) for v in columns.values()):
        return None
    for name in OPTIONAL_GUESS_COLUMNS:
        if complete(trajectory.get(name)):
            columns[name] = trajectory[name]
    return columns  # type: ignore[return-value]
