"""The problem model carries what downstream reads of the request as typed fields."""

from __future__ import annotations

import copy
import math

import pytest

from app.schemas import ProblemDocument
from worker.solver.problem import build_problem
from worker.solver.scenarios import get_scenario, list_scenarios
from worker.solver.trajectory import TIME_STATE_NAMES

SCENARIOS = [s.name for s in list_scenarios()]


@pytest.mark.parametrize("name", SCENARIOS)
def test_typed_fields_match_the_request(name: str) -> None:
    """Name, initial bank (radians) and terminal conditions in request units match the request;
    the request document itself is not carried along."""
    doc = ProblemDocument.model_validate(get_scenario(name).problem)
    model = build_problem(doc)
    assert not hasattr(model, "document")
    assert model.name == doc.name
    bank = doc.initial_state.bank_deg
    assert model.initial_bank == (math.radians(bank) if bank is not None else None)
    assert model.initial_bank_deg == bank
    for state in TIME_STATE_NAMES:
        spec = getattr(doc.terminal, state)
        given = model.terminal_si[state]
        assert given.kind == spec.kind
        assert given.value == getattr(spec, "value", None)
        assert given.lo == getattr(spec, "lo", None)
        assert given.hi == getattr(spec, "hi", None)


@pytest.mark.parametrize("bank_deg", [None, 0.0, -37.5, -79.3, 60.0])
def test_initial_bank_in_radians_or_none(bank_deg: float | None) -> None:
    """The initial bank is the request's angle in radians, bit for bit, or None when it is free."""
    raw = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    raw["initial_state"]["bank_deg"] = bank_deg
    model = build_problem(ProblemDocument.model_validate(raw))
    assert model.initial_bank_deg == bank_deg
    if bank_deg is None:
        assert model.initial_bank is None
    else:
        assert model.initial_bank == math.radians(bank_deg)


def test_range_and_soft_terminal_kept_in_request_units() -> None:
    """A range keeps its bounds and a soft target its value and weight, unconverted."""
    raw = copy.deepcopy(get_scenario("rlv-min-heat-load").problem)
    raw["terminal"]["altitude_m"] = {"kind": "range", "lo": 24000.0, "hi": 26000.0}
    raw["terminal"]["velocity_m_s"] = {"kind": "soft", "value": 760.0, "weight": 2.0}
    model = build_problem(ProblemDocument.model_validate(raw))
    assert model.terminal_si["altitude_m"].kind == "range"
    assert (model.terminal_si["altitude_m"].lo, model.terminal_si["altitude_m"].hi) == (
        24000.0,
        26000.0,
    )
    soft = model.terminal_si["velocity_m_s"]
    assert (soft.kind, soft.value, soft.weight) == ("soft", 760.0, 2.0)
