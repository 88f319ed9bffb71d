"""Several objective terms are minimized as the caller's weighted sum in the terms' own units
(s, m/s, deg, J/m^2), whatever each method's internal normalization: the pull of each term per
unit of its value is the caller's weight times one common factor, in every method."""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import pytest

from app.schemas import ProblemDocument
from worker.solver.methods.cheb_scvx.method import ChebScvx
from worker.solver.methods.energy_scp.method import EnergyScp
from worker.solver.methods.foh_ptr.method import FohPtr
from worker.solver.objective_weights import term_pulls, weighted_sum
from worker.solver.problem import build_problem
from worker.solver.scenarios import get_scenario


def test_a_single_term_keeps_its_weight() -> None:
    assert term_pulls([2.5], [1.0e6]) == [2.5]


def test_several_terms_pull_per_si_unit_as_their_weights() -> None:
    """pull_i / unit_i is proportional to w_i (1e-12: a few products), and the strongest pull
    is the largest weight."""
    weights, units = [1.0, 1.0e-6, 3.0], [10.0, 7.0e6, 0.5]
    pulls = term_pulls(weights, units)
    per_si = [p / u for p, u in zip(pulls, units, strict=True)]
    for w, k in zip(weights, per_si, strict=True):
        assert k / per_si[0] == pytest.approx(w / weights[0], rel=1e-12)
    assert max(pulls) == pytest.approx(max(weights), rel=1e-12)


def test_the_weighted_sum_negates_max_terms() -> None:
    values = {"min_time": 10.0, "max_terminal_velocity": 5.0}
    assert weighted_sum(values, {"min_time": 2.0, "max_terminal_velocity": 3.0}) == 5.0
    assert weighted_sum(values, {"min_time": 2.0}) is None


def _doc(scenario: str, terms: list[dict[str, Any]], method: dict[str, Any] | None = None) -> Any:
    raw = copy.deepcopy(get_scenario(scenario).problem)
    raw["objective"] = {"terms": terms}
    if method is not None:
        raw["method"] = method
    return ProblemDocument.model_validate(raw)


def test_foh_ptr_weighs_speed_and_heat_load_in_si_units() -> None:
    """d J / d V (per m/s) over d J / d Q (per J/m^2) of the normalized objective is minus the
    ratio of the caller's weights (1e-9: differences of a linear function)."""
    terms = [{"name": "max_terminal_velocity", "weight": 1.0},
             {"name": "min_heat_load", "weight": 2.0e-7}]  # fmt: skip
    doc = _doc("rlv-max-terminal-velocity", terms)
    method = FohPtr(build_problem(doc), doc.method)  # type: ignore[arg-type]
    method.linearize(method.start())  # the objective is normalized on the first reference
    objective = method.lin.objective
    assert objective is not None
    base = {"max_terminal_velocity": 900.0, "min_heat_load": 7.0e8}
    n0 = objective.normalized(base)
    d_v = objective.normalized({**base, "max_terminal_velocity": 901.0}) - n0
    d_q = objective.normalized({**base, "min_heat_load": 7.0e8 + 1.0e4}) - n0
    assert (d_q / 1.0e4) / d_v == pytest.approx(-2.0e-7, rel=1e-9)


def test_energy_scp_weighs_heat_load_and_latitude_in_si_units() -> None:
    """The heat load's pull per J/m^2 over the final latitude's per degree is the ratio of the
    caller's weights (1e-12)."""
    terms = [{"name": "min_heat_load", "weight": 1.0e-6},
             {"name": "max_final_latitude", "weight": 10.0}]  # fmt: skip
    doc = _doc("rlv-min-heat-load", terms)
    method = EnergyScp(build_problem(doc), doc.method)  # type: ignore[arg-type]
    method.start()
    obj = method.objective
    heat = obj.pull["min_heat_load"] / obj.scale["min_heat_load"]
    latitude = obj.pull["max_final_latitude"] / math.degrees(obj.scale["max_final_latitude"])
    assert heat / latitude == pytest.approx(1.0e-7, rel=1e-12)


def test_cheb_scvx_weighs_time_and_heat_load_in_si_units() -> None:
    """The final time's weight per second over the heat load's per J/m^2 is the ratio of the
    caller's weights (1e-12)."""
    terms = [{"name": "min_time", "weight": 1.0}, {"name": "min_heat_load", "weight": 3.0e-6}]
    raw = copy.deepcopy(get_scenario("cav-h-min-time").problem)
    raw["objective"] = {"terms": terms}
    raw["path_constraints"] = {"heat_rate": {"max_W_m2": 5.0e6, "k_q": 1.0e-4}}
    doc = ProblemDocument.model_validate(raw)
    problem = build_problem(doc)
    method = ChebScvx(problem, doc.method, problem.planet_model)  # type: ignore[arg-type]
    setup = method.setup
    per_second = setup.objective_time / problem.scales.time_s
    per_joule = setup.objective_heat / problem.scales.time_s
    assert per_joule / per_second == pytest.approx(3.0e-6, rel=1e-12)
    assert np.isfinite(per_joule)
