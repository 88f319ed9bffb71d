"""The pseudospectral method (paper 003) refuses, naming the field, what it cannot handle, and
its options refuse a mesh that does not divide."""

from __future__ import annotations

import copy
from typing import Any

import pytest
from pydantic import ValidationError

from app.schemas import ProblemDocument
from worker.solver.methods import check_support
from worker.solver.scenarios import get_scenario


def _raw() -> dict[str, Any]:
    return copy.deepcopy(get_scenario("rlv-min-time-hp").problem)


def _issues(raw: dict[str, Any]) -> dict[str, str]:
    return {i.field: i.message for i in check_support(ProblemDocument.model_validate(raw))}


def test_the_scenario_is_supported() -> None:
    assert _issues(_raw()) == {}


@pytest.mark.parametrize(
    ("change", "field", "words"),
    [
        (
            lambda r: r["vehicle"].update(angle_of_attack={"mode": "velocity_schedule"}),
            "vehicle.angle_of_attack",
            "optimizes the angle of attack",
        ),
        (
            lambda r: r.update(final_time={"kind": "fixed", "value_s": 1400}),
            "final_time",
            "free final time",
        ),
        (
            lambda r: r.update(
                waypoints=[{"latitude_deg": 30, "longitude_deg": 2, "radius_km": 50, "order": 1}]
            ),
            "waypoints",
            "waypoints",
        ),
        (
            lambda r: r.update(objective="min_heat_load"),
            "objective.terms[0].name",
            "cannot optimize",
        ),
    ],
)
def test_refused_with_the_field(change: Any, field: str, words: str) -> None:
    raw = _raw()
    change(raw)
    issues = _issues(raw)
    assert field in issues, issues
    assert words in issues[field]


def test_a_mesh_that_does_not_divide_is_refused_at_intervals() -> None:
    raw = _raw()
    raw["method"] = {"name": "hp-scp", "nodes": 80, "intervals": 20}
    with pytest.raises(ValidationError) as err:
        ProblemDocument.model_validate(raw)
    locs = [e["loc"] for e in err.value.errors()]
    assert any(loc[-1] == "intervals" for loc in locs), locs
