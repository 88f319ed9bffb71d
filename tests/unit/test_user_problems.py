"""The user-problem generator (bench.user_problems.generate): deterministic, valid documents.

The suite's problems are data committed with their references; these checks keep the generator
that wrote them reproducible: a problem is a pure function of (seed, index), every document
passes the contract, and the problems made infeasible on purpose say so with their argument;
the scorer reads which constraint a failure names.
"""

from __future__ import annotations

import json
from functools import cache
from typing import Any

from app.schemas import ProblemDocument
from bench.user_problems.__main__ import named_constraints
from bench.user_problems.generate import INFEASIBLE_EVERY, SEED, generate

INDICES = (1, INFEASIBLE_EVERY - 1, 2 * INFEASIBLE_EVERY - 1)
"""A feasible-by-construction problem and two infeasible on purpose (different causes)."""


@cache
def _generated(index: int) -> str:
    """generate(index) as JSON, once per module (each costs a lift-up propagation)."""
    return json.dumps(generate(index))


def _entry(index: int) -> dict[str, Any]:
    return dict(json.loads(_generated(index)))


def test_same_seed_and_index_give_the_same_problem() -> None:
    """Generating twice gives byte-identical documents; another seed gives another problem."""
    assert json.dumps(generate(INDICES[0])) == _generated(INDICES[0])
    assert generate(INDICES[0], SEED + 1)["problem"] != _entry(INDICES[0])["problem"]


def test_documents_pass_the_contract_and_name_their_features() -> None:
    """Each document validates; its name starts with its index and carries its objective."""
    for index in INDICES:
        entry = _entry(index)
        ProblemDocument.model_validate(entry["problem"])
        assert entry["name"].startswith(f"{index:03d}-")
        assert entry["features"]["objective"] in entry["name"]
        assert entry["problem"]["name"] == entry["name"]


def test_infeasible_on_purpose_carry_their_argument() -> None:
    """Problems made infeasible name the cause and give the physical argument."""
    causes = set()
    for index in INDICES[1:]:
        features = _entry(index)["features"]
        assert features["infeasible_on_purpose"] is not None
        assert features["infeasibility_argument"]
        causes.add(features["infeasible_on_purpose"])
    assert len(causes) == 2
    assert _entry(INDICES[0])["features"]["infeasible_on_purpose"] is None


def test_a_failure_names_the_planted_constraint_whatever_its_spelling() -> None:
    """The messages write "heat-rate limit" and "final time"; the scorer must read them (an
    earlier keyword list missed the hyphen and counted 5 of 17 named messages as unnamed)."""
    record = {"features": {"infeasible_on_purpose": "heat_below_lift_up"}}
    heat = "infeasible before any iteration: the heat-rate limit 670 kW/m^2 is below the peak"
    assert named_constraints(record, heat) == {
        "named": ["heat_rate"],
        "names_constraint": True,
        "names_planted": True,
    }
    record["features"]["infeasible_on_purpose"] = "downrange_beyond_speed"
    assert named_constraints(record, heat)["names_planted"] is False
    late = "infeasible, likely because the final time 940 s is shorter than the flight needs"
    assert named_constraints(record, late)["names_planted"] is True
    plain = {"features": {"infeasible_on_purpose": None}}
    assert named_constraints(plain, "diverged at iteration 3") == {
        "named": [],
        "names_constraint": False,
    }
