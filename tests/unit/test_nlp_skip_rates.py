"""The skip-entry NLP of the benchmarks flies the solver's physics: its CasADi rates, path values
and US76 density equal ``PoweredModel``'s and the atmosphere's at random points."""

from __future__ import annotations

import dataclasses

import casadi as ca  # the bench extra, installed by .ci/run with the dev extra
import numpy as np
import pytest

from app.schemas import ProblemDocument
from bench.nlp_skip import CasadiPowered, scenario_document
from worker.solver.atmosphere import US76Atmosphere
from worker.solver.models.powered import powered_path_values
from worker.solver.phased_problem import PhasedProblem, build_phased_problem

POINTS = 400


@pytest.fixture(scope="module")
def problem() -> PhasedProblem:
    return build_phased_problem(ProblemDocument.model_validate(scenario_document()))


def _points(problem: PhasedProblem, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Random states and controls over the flight's ranges (and beyond)."""
    rng = np.random.default_rng(seed)
    radius = problem.base.scales.radius_m
    thr = problem.model.thruster
    assert thr is not None and thr.lagged
    n = POINTS
    x = np.column_stack(
        [
            1.0 + rng.uniform(0.0, 150e3, n) / radius,
            rng.uniform(-3.0, 3.0, n),
            rng.uniform(-1.4, 1.4, n),
            rng.uniform(0.05, 1.2, n),
            rng.uniform(-1.2, 1.2, n),
            rng.uniform(-4.0, 4.0, n),
            rng.uniform(0.2, 1.0, n),
            rng.uniform(0.0, thr.max_thrust, n),
        ]
    )
    u = np.column_stack(
        [
            rng.uniform(-1.5, 1.5, n),
            rng.uniform(-1.6, 1.6, n),
            rng.uniform(0.0, thr.max_thrust, n),
        ]
    )
    return x, u


@pytest.mark.parametrize("omega", [None, 0.3])
def test_rates_equal_powered_model(problem: PhasedProblem, omega: float | None) -> None:
    """Every rate to 1e-10 relative, over a non-rotating planet (the scenario's) and a
    rotating one."""
    if omega is not None:
        problem = dataclasses.replace(
            problem, model=dataclasses.replace(problem.model, omega=omega)
        )
    x, u = _points(problem, 1 if omega is None else 2)
    f, _ = CasadiPowered(problem).functions(problem.phases[0].limits)
    got = f.map(POINTS)(x.T, u.T).full().T
    want = problem.model.rates(x, u)
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=0.0)


def test_heat_rate_equals_solver(problem: PhasedProblem) -> None:
    limits = problem.phases[0].limits
    assert limits.heat_max_W_m2 is not None
    x, u = _points(problem, 3)
    _, g = CasadiPowered(problem).functions(limits)
    got = g.map(POINTS)(x.T, u.T).full().ravel() * limits.heat_max_W_m2
    want = powered_path_values(problem.model, limits, x, u).heat_rate
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=0.0)


def test_us76_density_equals_solver(problem: PhasedProblem) -> None:
    """The B-spline of ln(rho) is the solver's PCHIP: equal to rounding between the table's
    nodes, at the layer bases and beyond both ends of the table."""
    rng = np.random.default_rng(4)
    h = np.concatenate(
        [rng.uniform(-20e3, 1.05e6, 300), [0.0, 11019.1, 47350.1, 50000.0, 86000.0, 1e6]]
    )
    sym = ca.MX.sym("h")
    log_rho = ca.Function("log_rho", [sym], [CasadiPowered(problem).log_density(sym)])
    got = np.exp(log_rho.map(h.size)(h[None, :]).full().ravel())
    want, _ = US76Atmosphere().density(h)
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=0.0)
