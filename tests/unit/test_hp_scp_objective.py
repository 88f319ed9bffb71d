"""Paper 003's objective terms in its subproblem: a single term pulls per trust unit of what it
measures, several keep the caller's weights between them in SI units, and the control effort
(the integral of |alpha'| + |sigma'|, paper 003's J0 term) is modelled exactly in the rates and
to first order in the final time."""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import pytest

from app.schemas import ProblemDocument
from app.schemas.methods.hp_scp import HpScpOptions
from worker.solver.methods.hp_scp.linearization import HpIterate, linearize
from worker.solver.methods.hp_scp.method import EFFORT_UNIT_DEG, HpScp
from worker.solver.methods.hp_scp.subproblem import effort_integral
from worker.solver.problem import build_problem
from worker.solver.scenarios import get_scenario

J0_WEIGHTS = {"min_time": 0.124, "min_control_effort": 1.745}


def _method(objective: Any) -> HpScp:
    raw = copy.deepcopy(get_scenario("rlv-min-time-hp").problem)
    raw["objective"] = objective
    doc = ProblemDocument.model_validate(raw)
    options = doc.method
    assert isinstance(options, HpScpOptions)
    method = HpScp(build_problem(doc), options)
    method.start()
    return method


def test_a_single_term_pulls_per_trust_unit() -> None:
    method = _method("min_time")
    assert method.objective is not None
    assert method.objective.tf == 1.0 / method.units.t
    assert method.objective.effort == 0.0


def test_several_terms_keep_the_callers_weights_in_si_units() -> None:
    """The effort's pull per degree over the time's pull per second is the caller's weight ratio
    (1e-12: a few products)."""
    terms = [{"name": n, "weight": w} for n, w in J0_WEIGHTS.items()]
    method = _method({"terms": terms})
    obj = method.objective
    assert obj is not None
    per_second = obj.tf / method.problem.scales.time_s
    per_degree = obj.effort * math.radians(1.0)
    ratio = J0_WEIGHTS["min_control_effort"] / J0_WEIGHTS["min_time"]
    assert per_degree / per_second == pytest.approx(ratio, rel=1e-12)
    # the term of the largest weight x trust unit (time: 0.124 x 10 s against the effort's
    # 1.745 x 0.5 deg) pulls per trust unit as hard as the largest weight
    assert obj.tf * method.units.t == pytest.approx(1.745, rel=1e-12)
    assert obj.effort * math.radians(EFFORT_UNIT_DEG) < 1.745


def test_the_effort_is_the_integral_of_the_rates_magnitudes() -> None:
    """On rates that are polynomial of degree <= the mesh's and of one sign per interval, the
    composite Clenshaw-Curtis sum is the exact integral (1e-12)."""
    method = _method("min_control_effort")
    ref = method.start()
    t = ref.pattern.mesh.points(0.0, 1.0)
    w = np.column_stack([2.0 + t**2, -(1.0 + t)])
    it = HpIterate(ref.z, w, 2.0, ref.pattern)
    exact = 2.0 * ((2.0 + 1.0 / 3.0) + (1.0 + 0.5))
    assert effort_integral(it) == pytest.approx(exact, rel=1e-12)


def test_the_subproblem_predicts_the_effort_to_first_order() -> None:
    """q x less the reference's effort is the effort's change: exact in the rates (the columns
    e >= |w| / u_w at equality), first order in the final time (the product t_f S linearized),
    so halving the step quarters the model's error."""
    terms = [{"name": n, "weight": w} for n, w in J0_WEIGHTS.items()]
    method = _method({"terms": terms})
    ref = method.start()
    rng = np.random.default_rng(4)
    signs = rng.choice([-1.0, 1.0], size=ref.w.shape)  # rates away from zero: no sign flips
    rates = signs * (1.0 + rng.random(ref.w.shape)) * method.units.w
    ref = HpIterate(ref.z, rates, ref.tf, ref.pattern)
    lin = linearize(method.problem, ref)
    method.subproblem(ref, lin, 1)
    cols, units = method.cols, method.units
    assert cols is not None and cols.E == 2 * cols.K
    direction_w = rng.normal(size=ref.w.shape)
    errors = []
    for scale in (1e-2, 5e-3):
        x = np.zeros(cols.n)
        dw = scale * direction_w
        dtf = scale * 3.0
        x[cols.w : cols.t] = dw.ravel()
        x[cols.t] = dtf
        new = HpIterate(ref.z, ref.w + dw * units.w, ref.tf + dtf * units.t, ref.pattern)
        x[cols.effort : cols.effort + cols.E] = (np.abs(new.w) / units.w).ravel()
        predicted = method.objective_value(ref) + float(method.q @ x)
        predicted -= method._effort_anchor(ref)
        errors.append(abs(method.objective_value(new) - predicted))
    assert errors[0] > 0.0
    assert errors[1] / errors[0] == pytest.approx(0.25, rel=1e-6)
