"""The typed result contract: one JSON conversion, nested records checked, dynamics provenance."""

from __future__ import annotations

import copy
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from app.schemas import ProblemDocument
from app.schemas.result import ResultDocument, json_ready
from worker.solver.problem import build_problem
from worker.solver.result import dynamics_path
from worker.solver.scenarios import get_scenario

EXAMPLE = Path(__file__).parents[2] / "app" / "routes" / "example_result_succeeded.json"


@dataclass
class _Point:
    x: float
    y: np.ndarray


def test_json_ready_makes_strict_json_and_keeps_every_float() -> None:
    value = {
        "a": [1.0, math.nan, -math.inf, np.float64(0.1), np.int64(3)],
        "b": (1, "x", True, None),
        "c": np.array([[1e-300, np.nan]]),
        "d": _Point(2.5, np.arange(2.0)),
        7: object,
    }
    clean = json_ready(value)
    assert clean == {
        "a": [1.0, None, None, 0.1, 3],
        "b": [1, "x", True, None],
        "c": [[1e-300, None]],
        "d": {"x": 2.5, "y": [0.0, 1.0]},
        "7": str(object),
    }
    assert type(clean["a"][3]) is float and type(clean["a"][4]) is int
    json.dumps(clean, allow_nan=False)


def test_nested_records_are_checked() -> None:
    document = json.loads(EXAMPLE.read_text())
    ResultDocument.model_validate(document)
    changes = (
        lambda d: d["verification"].update(surprise=1),
        lambda d: d["verification"]["path_maxima"].update(x={}),
        lambda d: d["verification"]["integrator"].pop("steps"),
        lambda d: d["provenance"].update(dynamics="fortran"),
        lambda d: d["timing"].update(wall_s="fast"),
    )
    for change in changes:
        broken = copy.deepcopy(document)
        change(broken)
        with pytest.raises(ValidationError):
            ResultDocument.model_validate(broken)


def _problem(atmosphere: dict[str, Any] | None = None) -> Any:
    document = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    if atmosphere is not None:
        document["planet"]["atmosphere"] = atmosphere
    return build_problem(ProblemDocument.model_validate(document))


def test_provenance_says_whether_the_dynamics_have_a_compiled_form() -> None:
    assert dynamics_path(_problem()) == {"dynamics": "compiled"}
    us76 = dynamics_path(_problem({"model": "us76"}))
    assert us76["dynamics"] == "numpy"
    assert "atmosphere" in us76["dynamics_note"] and "\n" not in us76["dynamics_note"]
