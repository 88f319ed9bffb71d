"""foh-ptr with a free final time: what its check accepts and refuses, the flight time its start
takes from the constant-bank sweep, and the final-time rows of its subproblem (no solve here;
the headline problem is solved in tests/unit/test_free_time_auto.py)."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.schemas import ProblemDocument
from app.schemas.methods import FohPtrOptions
from worker.solver.api import solve_problem
from worker.solver.methods import check_support
from worker.solver.methods.foh_ptr.method import FohPtr
from worker.solver.problem import build_problem
from worker.solver.transcription.time_grid import (
    _sweep_candidates,
    free_sweep,
    propagate_constant_bank,
    uniform_intervals,
)

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "user-free-time-min-heat.json"


def _raw(**changes: Any) -> dict[str, Any]:
    raw: dict[str, Any] = json.loads(EXAMPLE.read_text())
    raw["method"] = {"name": "foh-ptr"}
    raw.update(copy.deepcopy(changes))
    return raw


def _fields(raw: dict[str, Any]) -> set[str]:
    return {i.field for i in check_support(ProblemDocument.model_validate(raw))}


def test_a_free_final_time_is_accepted_and_min_time_is_not_yet() -> None:
    """min_time is refused: with the interval trust weight of a fixed final time the method
    stopped at 1361.9 s where the NLP reaches 1157.3 s (docs/methods/foh-ptr.md)."""
    assert _fields(_raw()) == set()
    assert _fields(_raw(final_time={"kind": "free", "max_s": 2000})) == set()
    assert _fields(_raw(objective="min_time")) == {"objective.terms[0].name"}


def test_what_a_free_final_time_cannot_do_is_refused_with_its_field() -> None:
    uniform = _raw()
    uniform["method"]["grid"] = "uniform"
    assert _fields(uniform) == {"method.grid"}
    no_end = _raw()
    no_end["terminal"] = {"longitude_deg": 30, "latitude_deg": 55}
    assert _fields(no_end) == {"final_time"}


def test_the_sweep_ends_each_flight_at_the_terminal_altitude() -> None:
    """Each bank's crossing time flies it to 25 km: within 100 m (the sweep interpolates
    linearly within a 5 s step of a flight descending at most ~200 m/s there)."""
    problem = build_problem(ProblemDocument.model_validate(_raw()))
    candidates = _sweep_candidates(problem)
    score, times = free_sweep(problem, candidates)
    assert np.isfinite(score).any()
    best = int(np.argmin(score))
    t_end = float(times[best])
    steps = math.ceil(t_end * problem.scales.time_s / 5.0)
    z = propagate_constant_bank(
        problem, np.radians(candidates[best : best + 1]), uniform_intervals(t_end, steps + 1)
    )
    altitude = (z[0, -1, 0] - 1.0) * problem.scales.radius_m
    assert abs(altitude - 25_000.0) < 100.0


def _blocks(raw: dict[str, Any]) -> set[str]:
    doc = ProblemDocument.model_validate(raw)
    method = FohPtr(build_problem(doc), FohPtrOptions())
    return {blk.name for blk in method.sub.rows.blocks}


def test_the_sum_of_the_intervals_is_free_bounded_or_fixed() -> None:
    free = _blocks(_raw())
    assert "final_time" not in free and "final_time_max" not in free
    bounded = _blocks(_raw(final_time={"kind": "free", "max_s": 1500}))
    assert "final_time_max" in bounded and "final_time" not in bounded
    fixed = _blocks(_raw(final_time={"kind": "fixed", "value_s": 1400}))
    assert "final_time" in fixed and "final_time_max" not in fixed


SUITE = Path(__file__).resolve().parents[2] / "bench" / "user_problems" / "data"


@pytest.mark.slow
def test_a_final_time_far_from_the_starts_is_reached() -> None:
    """User-problem suite 009 (RLV, maximum final longitude, US76, bank-rate limit, free final
    time): the starts fly about 1 270 s, the NLP optimum 1 879.5 s. With the final time's
    change weighted like the sliding of the nodes (weight_trust_final_time 100) the final time
    moved about 1 s an iteration and both starts stopped at their iteration limit; now it must
    succeed within 0.5 % of the NLP reference (the suite's bar; here 0.02 % measured)."""
    record = json.loads(next(SUITE.glob("009-*.json")).read_text())
    raw = copy.deepcopy(record["problem"])
    raw["method"] = {"name": "foh-ptr"}
    result = solve_problem(ProblemDocument.model_validate(raw))
    assert result["status"] == "succeeded", result.get("failure")
    reference = record["objective"]["value"]
    assert abs(result["objective"]["value"] / reference - 1.0) <= 0.005
    starts = {h["extra"]["start"]: h["extra"]["node_times_s"][-1] for h in result["history"][:1]}
    assert result["trajectory"]["time_s"][-1] - min(starts.values()) > 500.0
