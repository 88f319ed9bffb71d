"""foh-ptr with a second held attitude state: an optimized angle of attack (or a parabolic
polar's normalized lift) as a state, its rate as a second first-order-hold control.

The discretization and the sampled heat load are checked against differences of the propagation
itself (independent of the sensitivity equations; the curvature in ``test_foh_hessian``); the
held attitude against
its own integral; the solves against independent references: Betts' published Shuttle maximum
crossrange and the NLP references of the user-problem suite.
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest

from app.schemas import ProblemDocument
from app.schemas.guess import GUESS_COLUMNS, OPTIONAL_GUESS_COLUMNS
from worker.solver.api import solve_problem
from worker.solver.methods.foh_ptr.alpha_state import (
    HeldAttitude,
    held_alpha,
    held_alpha_problem,
    with_alpha,
)
from worker.solver.methods.foh_ptr.objective import TimeObjective, quadrature_weights
from worker.solver.problem import EntryProblem, build_problem
from worker.solver.scenarios import get_scenario
from worker.solver.transcription.foh_exact import foh_exact, propagate_nodes
from worker.solver.transcription.foh_model import ALPHA_BANK_MODEL, foh_model
from worker.solver.transcription.time_grid import initial_reference

SUITE = Path(__file__).resolve().parents[2] / "bench" / "user_problems" / "data"
MODEL = ALPHA_BANK_MODEL
NZ, M = 8, 2


@pytest.fixture(scope="module")
def problem() -> EntryProblem:
    raw = copy.deepcopy(get_scenario("shuttle-max-crossrange-heat-limited").problem)
    return build_problem(ProblemDocument.model_validate(raw))


def _reference(problem: EntryProblem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The first 12 nodes of the start's 40-node held-alpha flight (intervals near 90 s, made
    unequal) with both rates changing sign."""
    alpha = held_alpha(problem, MODEL.unit)
    start = initial_reference(held_alpha_problem(problem, alpha, MODEL.unit), 40, None)
    ref = with_alpha(start, alpha)
    z, s = ref.z[:12], ref.s[:11] * np.linspace(0.7, 1.3, 11)
    w = ref.w[:12].copy()
    w[:, 0] = np.radians(0.3) * problem.scales.time_s * np.cos(np.arange(12))
    w[:, 1] = np.radians(0.05) * problem.scales.time_s * np.sin(np.arange(12))
    return z, w, s


def test_the_model_follows_the_vehicle(problem: EntryProblem) -> None:
    assert foh_model(problem) is ALPHA_BANK_MODEL
    polar = json.loads(next(SUITE.glob("038-*.json")).read_text())["problem"]
    assert foh_model(build_problem(ProblemDocument.model_validate(polar))).unit == 1.0
    # the start's alpha: the largest L/D of Betts' polynomials within 0-45 deg at Mach 10
    assert 10.0 < math.degrees(held_alpha(problem, MODEL.unit)) < 25.0


def test_maps_match_central_differences(problem: EntryProblem) -> None:
    """Phi (8 x 8), B- and B+ (8 x 2 each) and S against central differences of the propagation
    (step 1e-6: O(h^2) truncation near 1e-10, far inside the 1e-5 relative bound)."""
    z, w, s = _reference(problem)
    dyn = MODEL.dynamics
    maps = foh_exact(z, w, s, problem.forces, problem.omega, substeps=6, dynamics=dyn)
    assert maps.Bm.shape == (s.size, NZ, M) and maps.jacobian.shape == (s.size, NZ, NZ + 2 * M + 1)
    h, k = 1e-6, 4

    def prop(z: np.ndarray, w: np.ndarray, s: np.ndarray) -> np.ndarray:
        return propagate_nodes(z, w, s, problem.forces, problem.omega, 6, dynamics=dyn)[k]

    def diff(bump: np.ndarray, which: str) -> np.ndarray:
        args = {"z": z, "w": w, "s": s}
        plus, minus = dict(args), dict(args)
        plus[which] = args[which] + h * bump
        minus[which] = args[which] - h * bump
        return (prop(**plus) - prop(**minus)) / (2 * h)

    for c in range(M):
        for node, block in ((k, maps.Bm), (k + 1, maps.Bp)):
            bump = np.zeros_like(w)
            bump[node, c] = 1.0
            assert np.allclose(diff(bump, "w"), block[k][:, c], rtol=1e-5, atol=1e-8)
    bump_s = np.zeros_like(s)
    bump_s[k] = 1.0
    assert np.allclose(diff(bump_s, "s"), maps.S[k], rtol=1e-5, atol=1e-7)
    for j in range(NZ):
        bump_z = np.zeros_like(z)
        bump_z[k, j] = 1.0
        assert np.allclose(diff(bump_z, "z"), maps.Phi[k][:, j], rtol=1e-4, atol=1e-6)


def test_the_sampled_heat_load_and_its_gradient(problem: EntryProblem) -> None:
    """Simpson's rule over the substeps against a fine integration of the same intervals, and
    the gradient against central differences of the sampled load itself."""
    z, w, s = _reference(problem)
    objective = TimeObjective(problem, MODEL.layout.trust_units(problem.scales), z, s, 7)

    def sampled(z: np.ndarray, w: np.ndarray, s: np.ndarray, substeps: int = 12) -> tuple:
        maps = foh_exact(
            z, w, s, problem.forces, problem.omega, substeps, samples=True, dynamics=MODEL.dynamics
        )
        assert maps.samples is not None
        return objective.sampled_heat(maps.samples, s)

    load, block = sampled(z, w, s)
    fine, _ = sampled(z, w, s, 96)
    assert abs(load / fine - 1.0) < 1e-4  # Simpson on 12 steps: well under the 0.5 % target
    h, k = 1e-6, 5
    unit = objective.problem.scales.time_s  # block is d(load / time unit)
    for col in (0, 3, 7):  # radius, speed, alpha at the interval's start
        bump = np.zeros_like(z)
        bump[k, col] = h
        num = (sampled(z + bump, w, s)[0] - sampled(z - bump, w, s)[0]) / (2 * h * unit)
        assert math.isclose(block[k, col], num, rel_tol=1e-5, abs_tol=1e-9 * abs(num) + 1e-12)
    bump_s = np.zeros_like(s)
    bump_s[k] = h
    num = (sampled(z, w, s + bump_s)[0] - sampled(z, w, s - bump_s)[0]) / (2 * h * unit)
    assert math.isclose(block[k, -1], num, rel_tol=1e-5)
    assert np.allclose(quadrature_weights(13).sum(), 1.0) and np.allclose(
        quadrature_weights(4).sum(), 1.0
    )


def test_the_held_attitude_integrates_its_rates() -> None:
    t = np.array([0.0, 0.5, 1.5, 2.0])
    rates = np.array([[0.2, -0.1], [-0.4, 0.3], [0.1, 0.0], [0.3, -0.2]])
    bank = np.array([0.1, 0.0, 0.0, 0.0])
    alpha = np.array([0.3, 0.0, 0.0, 0.0])
    for k in range(3):  # nodes consistent with the held rates: the trapezoid of a linear rate
        h = t[k + 1] - t[k]
        bank[k + 1] = bank[k] + 0.5 * h * (rates[k, 0] + rates[k + 1, 0])
        alpha[k + 1] = alpha[k] + 0.5 * h * (rates[k, 1] + rates[k + 1, 1])
    path = HeldAttitude(t, bank, alpha, rates)
    at_nodes = path.at(t)
    assert np.allclose(at_nodes[0], bank) and np.allclose(at_nodes[1], np.degrees(alpha))
    fine = np.linspace(0.0, 2.0, 4001)
    sigma, alpha_deg = path.at(fine)
    d_sigma, d_alpha = path.rates_at(fine)
    assert np.allclose(np.gradient(sigma, fine)[1:-1], d_sigma[1:-1], atol=2e-3)
    assert np.allclose(np.gradient(np.radians(alpha_deg), fine)[1:-1], d_alpha[1:-1], atol=2e-3)


def _suite(prefix: str) -> tuple[dict, dict]:
    record = json.loads(next(SUITE.glob(f"{prefix}-*.json")).read_text())
    return record, record["problem"]


def test_the_shuttle_reaches_betts_crossrange_and_restarts_from_its_answer() -> None:
    """Betts' Shuttle maximum crossrange (paper 003's case): 34.1412 deg published, 34.14118
    by our NLP at 200 intervals; 0.01 % is two orders inside the suite's 0.5 %. Its answer,
    angle of attack included, given back as the initial guess: the same optimum to 1e-5 (one
    local solution reached twice) in fewer iterations."""
    raw = copy.deepcopy(get_scenario("shuttle-max-crossrange").problem)
    raw["method"] = {"name": "foh-ptr"}
    result = solve_problem(ProblemDocument.model_validate(raw))
    assert result["status"] == "succeeded", result["failure"]
    assert abs(result["objective"]["value"] / 34.1412 - 1.0) < 1e-4
    assert result["verification"]["feasible"]
    columns = (*GUESS_COLUMNS, *OPTIONAL_GUESS_COLUMNS)
    guess = {name: result["trajectory"][name] for name in columns}
    warm = solve_problem(
        ProblemDocument.model_validate({**raw, "initial_guess": {"trajectory": guess}})
    )
    assert warm["status"] == "succeeded", warm["failure"]
    assert warm["provenance"]["initial_guess"].startswith("the given trajectory")
    assert warm["timing"]["iterations"] < result["timing"]["iterations"]
    assert warm["objective"]["value"] == pytest.approx(result["objective"]["value"], rel=1e-5)


@pytest.mark.parametrize(
    ("prefix", "nodes"),
    [
        ("052", 80),  # Shuttle minimum heat load, heat-rate and dynamic-pressure limits active
        ("038", 80),  # CAV-H parabolic polar, maximum terminal speed, zone beside the path
    ],
)
def test_suite_problems_meet_their_nlp_references(prefix: str, nodes: int) -> None:
    """Within the suite's acceptance (0.5 % of the two-mesh NLP reference), judged on the flown
    heat load where the result has one."""
    record, raw = _suite(prefix)
    raw["method"] = {"name": "foh-ptr", "nodes": nodes}
    result = solve_problem(ProblemDocument.model_validate(raw))
    assert result["status"] == "succeeded", result["failure"]
    entry = result["objective"]
    value = entry["propagated_value"] if entry["propagated_value"] is not None else entry["value"]
    reference = record["objective"]["value"]
    sign = 1.0 if record["objective"]["name"].startswith("min") else -1.0
    assert sign * (value - reference) / abs(reference) < 0.005, (value, reference)
