"""Each method refuses, at validation, node counts below what it can use, naming
``method.nodes`` and the minimum (found by trying each method on its built-in problems:
docs/problem-contract.md, "Method")."""

from __future__ import annotations

from typing import Any

import pytest
from pydantic import ValidationError

from app.schemas import ProblemDocument, issues_from_validation_error
from app.submission import apply_overrides
from worker.solver.scenarios import get_scenario


def _issues(scenario: str, method: dict[str, Any]) -> list[tuple[str, str, str]]:
    document = apply_overrides(get_scenario(scenario).problem, {"method": method})
    try:
        ProblemDocument.model_validate(document)
    except ValidationError as exc:
        return [(i.field, i.code, i.message) for i in issues_from_validation_error(exc)]
    return []


def test_foh_ptr_needs_nine_nodes() -> None:
    ((field, code, message),) = _issues("rlv-max-terminal-velocity", {"nodes": 8})
    assert (field, code) == ("method.nodes", "greater_than_equal")
    assert "greater than or equal to 9" in message
    assert _issues("rlv-max-terminal-velocity", {"nodes": 9}) == []


def test_cheb_scvx_needs_degree_two_in_every_interval() -> None:
    ((field, code, message),) = _issues("cav-h-min-time", {"nodes": 40, "intervals": 20})
    assert (field, code) == ("method.nodes", "too_few_nodes")
    assert "need 41 points or more" in message
    assert _issues("cav-h-min-time", {"nodes": 41, "intervals": 20}) == []
    assert _issues("cav-h-min-time", {"nodes": 3, "intervals": 1}) == []


def test_hp_scp_names_the_node_count_below_its_intervals() -> None:
    ((field, code, message),) = _issues("rlv-min-time-hp", {"nodes": 3})
    assert (field, code) == ("method.nodes", "too_few_nodes")
    assert "20 intervals of degree 1 at least need 21 points" in message
    ((field, code, _),) = _issues("rlv-min-time-hp", {"nodes": 30})  # 29 is no multiple of 20
    assert (field, code) == ("method.intervals", "mesh_shape")
    assert _issues("rlv-min-time-hp", {"nodes": 3, "intervals": 1}) == []


@pytest.mark.parametrize(
    ("scenario", "method"),
    [
        ("rlv-min-heat-load", {"nodes": 2}),
        ("shuttle-skip-min-propellant", {"nodes": 2, "degree": 1}),
    ],
)
def test_three_points_are_the_floor_elsewhere(scenario: str, method: dict[str, Any]) -> None:
    ((field, _, message),) = _issues(scenario, method)
    assert field == "method.nodes" and "3" in message
