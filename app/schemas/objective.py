"""The objective: a weighted sum of named performance terms."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, Field, model_validator

from app.schemas import bounds
from app.schemas.base import FieldProblem, StrictModel, raise_problems
from app.schemas.limits import MAX_OBJECTIVE_TERMS

ObjectiveName = Literal[
    "min_heat_load",
    "max_terminal_velocity",
    "min_time",
    "max_final_latitude",
    "min_final_latitude",
    "max_final_longitude",
    "min_final_longitude",
    "min_control_effort",
    "min_propellant",
]
"""Names of the performance terms a method may be asked to optimize."""


class ObjectiveTerm(StrictModel):
    """One term of the objective and its positive weight."""

    name: ObjectiveName = Field(..., description="Which performance measure to optimize.")
    weight: float = Field(
        1.0, gt=0, le=bounds.WEIGHT_MAX, description="Relative weight of the term, > 0."
    )


class Objective(StrictModel):
    """Weighted sum of distinct terms; the methods minimize it (max_* terms enter negated)."""

    terms: list[ObjectiveTerm] = Field(
        ...,
        min_length=1,
        max_length=MAX_OBJECTIVE_TERMS,
        description="The terms, each name at most once.",
    )

    @model_validator(mode="after")
    def _distinct(self) -> Objective:
        seen: set[str] = set()
        problems: list[FieldProblem] = []
        for i, term in enumerate(self.terms):
            if term.name in seen:
                problems.append(
                    FieldProblem(
                        ("terms", i, "name"),
                        "duplicate_term",
                        f"objective term {term.name!r} appears more than once",
                        term.name,
                    )
                )
            seen.add(term.name)
        raise_problems("Objective", problems)
        return self

    def names(self) -> list[str]:
        """Names of the terms, in order."""
        return [term.name for term in self.terms]


def _string_as_single_term(value: Any) -> Any:
    """Read a plain string as shorthand for ``{"terms": [{"name": string, "weight": 1}]}``."""
    if isinstance(value, str):
        return {"terms": [{"name": value}]}
    return value


ObjectiveInput = Annotated[Objective, BeforeValidator(_string_as_single_term)]
"""The objective as a document field; a plain string names a single term of weight 1."""
