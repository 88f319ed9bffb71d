"""The compiled path-limit rows against the numpy forms they replace, on the same points.

The kernel evaluates ln(p / p_max) as a sum of logarithms where numpy takes the logarithm of a
product, and the partials in a different order: they agree to a few ulps per operation, so
1e-12 of each quantity's scale bounds the difference, while an error in a formula shows at 1e-6
or far above. The smooth maximum is checked against its definition in test_between_nodes.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from app.schemas import ProblemDocument
from worker.solver.constraints.log_path import active_limits, log_path_rows, path_rows_at
from worker.solver.constraints.path_compiled import limit_parameters
from worker.solver.problem import EntryProblem, build_problem
from worker.solver.scenarios import get_scenario

Array = np.ndarray


def _problem(variant: str) -> EntryProblem:
    """Case 1 of paper 002 (all three limits), or a variant that takes the kernel's branches."""
    raw = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    paths = raw["path_constraints"]
    if variant == "heat-alpha-factor-constant-alpha":
        paths["heat_rate"]["alpha_polynomial"] = [1.2, -0.02, 4e-4, -3e-6]
        paths["heat_rate"]["velocity_exponent"] = 3.07
        raw["vehicle"]["angle_of_attack"] = {"mode": "constant", "alpha_deg": 25.0}
    elif variant == "heat-alpha-factor-scheduled":
        paths["heat_rate"]["alpha_polynomial"] = [1.2, -0.02, 4e-4]
    elif variant == "load-factor-only-cd-of-alpha":
        del paths["heat_rate"], paths["dynamic_pressure"]
        aero = raw["vehicle"]["aerodynamics"]
        aero["cd_argument"] = "alpha"
        aero["cd_coefficients"] = [0.07854, -0.0061592, 0.000621408]
    return build_problem(ProblemDocument.model_validate(raw))


VARIANTS = (
    "case-1",
    "heat-alpha-factor-constant-alpha",
    "heat-alpha-factor-scheduled",
    "load-factor-only-cd-of-alpha",
)


@pytest.mark.parametrize("variant", VARIANTS)
def test_log_rows_match_numpy(variant: str) -> None:
    p = _problem(variant)
    names = active_limits(p)
    params = limit_parameters(p, names)
    assert params is not None
    rng = np.random.default_rng(3)
    sc = p.scales
    # altitudes 20-80 km and speeds 800-7000 m/s: both branches of the alpha schedule
    r = 1.0 + rng.uniform(20e3, 80e3, 400) / sc.radius_m
    v = rng.uniform(800.0, 7000.0, 400) / sc.speed_m_s
    fast = path_rows_at(p, r, v, params)
    slow = log_path_rows(p, r, v, p.forces.terms(r, v))
    assert fast.names == slow.names == names
    for name in ("g", "g_r", "g_v"):
        a, b = getattr(fast, name), getattr(slow, name)
        scale = np.max(np.abs(b), axis=0)
        assert np.all(np.abs(a - b) <= 1e-12 * scale), name


def test_models_without_a_compiled_form_take_numpy() -> None:
    raw = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    raw["planet"]["atmosphere"] = {"model": "us76"}
    p = build_problem(ProblemDocument.model_validate(raw))
    assert limit_parameters(p, active_limits(p)) is None
