"""The NLP reference's model (bench.nlp_collocation) against the solver's own dynamics.

The transcription writes the equations and force models again from the contract; at sample
states its right-hand side and path quantities must equal the service's (``time_dynamics``,
``path_values``). Tolerance 1e-9 relative for the analytic models (two evaluations of the same
formulas in double precision); 1e-3 for the U.S. 1976 atmosphere, where the two sides
interpolate the standard differently (a B-spline on 200 m nodes here, PCHIP on 100 m nodes in
the service, each within 2.5e-4 of the standard).
"""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import pytest

from app.schemas import ProblemDocument
from bench.nlp_collocation import EntryNlp
from worker.solver.models.point_mass import time_dynamics
from worker.solver.path_limits import path_values
from worker.solver.problem import build_problem
from worker.solver.scenarios import get_scenario

STATES = np.array(
    [  # r, theta, phi, V, gamma, psi (nondimensional) at 80, 55, 35 km
        [1.0 + 80e3 / 6378e3, 0.1, 0.3, 0.95, -0.01, 0.6],
        [1.0 + 55e3 / 6378e3, 0.4, 0.7, 0.70, -0.03, 1.9],
        [1.0 + 35e3 / 6378e3, 0.9, -0.2, 0.40, -0.08, -1.1],
    ]
)
BANKS = (0.3, -0.9, 1.2)
ALPHAS_DEG = (30.0, 18.0, 9.0)


def _documents() -> dict[str, tuple[dict[str, Any], float]]:
    """Documents covering each model the transcription has, with their relative tolerance."""
    rlv = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    shuttle = copy.deepcopy(get_scenario("shuttle-max-crossrange-heat-limited").problem)
    us76 = copy.deepcopy(rlv)
    us76["planet"]["atmosphere"] = {"model": "us76"}
    table = copy.deepcopy(rlv)
    table["vehicle"]["angle_of_attack"] = {
        "mode": "table",
        "velocity_m_s": [1000.0, 3000.0, 6000.0],
        "alpha_deg": [12.0, 25.0, 38.0],
    }
    constant = copy.deepcopy(shuttle)
    constant["vehicle"]["angle_of_attack"] = {"mode": "constant", "alpha_deg": 17.0}
    return {
        "rlv rotating, CD(CL), schedule": (rlv, 1e-9),
        "shuttle CD(alpha), optimized alpha, heat alpha factor": (shuttle, 1e-9),
        "US76": (us76, 1e-3),
        "alpha table": (table, 1e-9),
        "alpha constant": (constant, 1e-9),
    }


@pytest.mark.parametrize("case", list(_documents()))
def test_rates_and_path_match_the_solver(case: str) -> None:
    """Rates and heat rate, dynamic pressure and load factor equal the service's."""
    document, rtol = _documents()[case]
    nlp = EntryNlp(document, 4, build=False)
    problem = build_problem(ProblemDocument.model_validate(document))
    # the same planet radius for both sides: the sample altitudes are relative to it
    states = STATES.copy()
    states[:, 0] = 1.0 + (STATES[:, 0] - 1.0) * 6378e3 / problem.scales.radius_m
    for y, bank, alpha in zip(states, BANKS, ALPHAS_DEG, strict=True):
        optimized = nlp.alpha_free
        att = math.radians(alpha) if optimized else None
        ours = np.array(nlp.rates(y.tolist(), bank, att)).ravel()
        u = np.array([[math.cos(bank), math.sin(bank)]])
        alpha_arg = np.array([alpha]) if optimized else None
        theirs = time_dynamics(y[None, :], u, problem.forces, problem.omega, alpha_arg,
                               jacobians=False).f[0]  # fmt: skip
        np.testing.assert_allclose(ours, theirs, rtol=rtol, atol=1e-12)
        ft = problem.forces.terms(y[None, 0], y[None, 3], alpha_arg)
        pv = path_values(problem.forces, problem.heat_model, y[None, 0], y[None, 3], ft)
        path = {k: float(np.array(v).ravel()[0]) for k, v in nlp.path(y.tolist(), att).items()}
        if problem.heat_model is not None:
            assert path["heat_rate"] == pytest.approx(float(pv.heat_rate[0]), rel=rtol)
        assert path["dynamic_pressure"] == pytest.approx(float(pv.dynamic_pressure[0]), rel=rtol)
        assert path["load_factor"] == pytest.approx(float(pv.load_factor[0]), rel=rtol)


def test_refuses_what_it_does_not_cover() -> None:
    """Waypoints and aerodynamic tables are refused by name, not silently dropped."""
    document = copy.deepcopy(get_scenario("cav-h-min-time-waypoints").problem)
    with pytest.raises(ValueError, match="waypoints"):
        EntryNlp(document, 4, build=False)
