"""energy-scp on variants of paper 000's case that its paper weights do not cover (issue 15): a
hard terminal point, a terminal objective, and the pieces that make them work (scaled terminal
objectives, bank-rate rows, the chatter stop rule, the lift-preserving projection, a smoothness
term that vanishes at convergence).

References are NLP collocation solutions stored as data in tests/variants/data (command, meshes,
IPOPT status, mesh check there). The objective tolerance is issue 15's acceptance, 0.3 %.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from tests.variants.cases import DATA, Variant, _load, relative_error
from worker.solver.api import solve_problem
from worker.solver.methods.energy_scp.controls import bank_chatter, lift_preserving
from worker.solver.methods.energy_scp.guess import energy_bounds, initial_guess
from worker.solver.methods.energy_scp.objective import TERMINAL_STEP_UNITS, EnergyObjective
from worker.solver.models.layout import ENERGY
from worker.solver.models.point_mass import energy_dynamics
from worker.solver.problem import build_problem
from worker.solver.transcription.energy_trapezoid import EnergyTrapezoid, SubproblemData

TOLERANCE = 0.003
"""Relative objective error allowed: issue 15's acceptance (0.3 % of the NLP reference)."""


def _variant(name: str) -> Variant:
    return _load(DATA / f"{name}.json")


def _solve(name: str) -> tuple[Variant, dict[str, Any]]:
    variant = _variant(name)
    return variant, solve_problem(variant.document())


@pytest.mark.slow
def test_hard_terminal_point_succeeds_verified_near_the_nlp_optimum() -> None:
    """Paper 000's case with its soft terminal longitude/latitude made hard: succeeded, verified
    and within 0.3 % of the NLP heat load (731.01 MJ/m^2; 961 nodes, mesh-checked)."""
    variant, result = _solve("energy-hard-terminal")
    assert result["status"] == "succeeded", result["failure"]
    assert result["verification"]["feasible"]
    assert relative_error(result["objective"]["value"], variant.reference_objective) <= TOLERANCE
    assert relative_error(result["objective"]["propagated_value"], variant.reference_objective) <= (
        TOLERANCE
    )
    err = {
        k: abs(v["error"]) for k, v in result["verification"]["terminal_error_vs_target"].items()
    }
    assert err["longitude_deg"] <= 0.1 and err["latitude_deg"] <= 0.1  # the verifier's own bounds
    # the bank-rate rows (5 deg/s by default) hold on the converged bank profile, to 5 % (they
    # bound the bank linearized at the reference, with the reference's interval times)
    traj = result["trajectory"]
    rate = np.abs(np.diff(traj["bank_deg"])) / np.diff(traj["time_s"])
    assert float(np.max(rate)) <= 5.0 * 1.05
    assert all("bank_chatter_nodes" not in h["extra"] for h in result["history"][-1:])


@pytest.mark.slow
def test_max_final_latitude_reaches_the_nlp_optimum() -> None:
    """A terminal objective moves at the trust region's rate: from the straight-line guess the
    final latitude reaches the NLP optimum (73.15 deg) within 0.3 %, verified, within 20
    iterations (divided by its value, the term moved ~1 deg per iteration)."""
    variant, result = _solve("energy-max-final-latitude")
    assert result["status"] == "succeeded", result["failure"]
    assert result["verification"]["feasible"]
    assert relative_error(result["objective"]["value"], variant.reference_objective) <= TOLERANCE
    assert result["timing"]["iterations"] <= 20
    first = result["history"][0]["max_state_change"]["latitude_deg"]
    assert first >= 10.0  # the first step alone moves the latitude by more than 10 deg


def test_terminal_objective_scale_follows_the_trust_region() -> None:
    """A terminal term is worth 2 w_tr (K/3) TERMINAL_STEP_UNITS per trust unit of its state."""
    doc = _variant("energy-max-final-latitude").document()
    problem = build_problem(doc)
    scale = ENERGY.trust_units(problem.scales)
    e = np.linspace(*energy_bounds(problem), 61)
    x, u = initial_guess(problem, e)
    ed = energy_dynamics(x, u, e, problem.forces, problem.omega)
    objective = EnergyObjective(problem, e, x, ed, scale, 0.005)
    gain = 2.0 * 0.005 * (61 / 3.0) * TERMINAL_STEP_UNITS
    assert objective.scale["max_final_latitude"] == pytest.approx(scale[2] / gain, rel=1e-12)
    _, terminal = objective.gradients(x, ed)
    assert terminal[2] * scale[2] == pytest.approx(-gain, rel=1e-12)  # maximize: negative


def test_bank_chatter_is_detected_and_a_smooth_reversal_is_not() -> None:
    """A node-to-node zigzag is chatter; one bank reversal, however fast, is not."""
    zigzag = np.radians([10.0, 10.0, 60.0, -40.0, 60.0, -40.0, 10.0])
    reversal = np.radians([30.0, 30.0, 10.0, -20.0, -45.0, -50.0, -50.0])

    def as_u(bank: np.ndarray) -> np.ndarray:
        return np.column_stack([np.cos(bank), np.sin(bank)])

    assert bank_chatter(as_u(zigzag), 10.0) == 3
    assert bank_chatter(as_u(reversal), 10.0) == 0
    assert bank_chatter(as_u(zigzag), 120.0) == 0  # steps of 100 deg are below 120


def test_lift_preserving_projection_keeps_vertical_lift_on_the_circle() -> None:
    """Controls inside the disc move onto |u| = 1 with the same cos(bank); on it they stay."""
    u = np.array([[0.4, 0.1], [0.5, 0.0], [0.6, -0.2], [math.cos(0.3), math.sin(0.3)]])
    ref = np.array([[1.0, 0.0], [0.8, -0.6], [1.0, 0.0], [1.0, 0.0]])
    out = lift_preserving(u, ref)
    assert np.allclose(np.linalg.norm(out, axis=1), 1.0)
    assert np.allclose(out[:, 0], u[:, 0])
    assert np.sign(out[0, 1]) == 1 and np.sign(out[1, 1]) == -1 and np.sign(out[2, 1]) == -1
    assert np.array_equal(out[3], u[3])


def test_control_smoothness_vanishes_at_the_reference() -> None:
    """The smoothness term acts on the step of the control differences: at the reference its
    gradient is zero, so it does not bias a converged solution (only the trust region's and the
    regularization's terms remain, and both are zero here)."""
    K = 9
    e = np.linspace(0.55, 0.98, K)
    rng = np.random.default_rng(1)
    bank = rng.uniform(-1.2, 1.2, K)  # a chattering reference: the old penalty pulled on it
    u_ref = np.column_stack([np.cos(bank), np.sin(bank)])
    tr = EnergyTrapezoid(
        e,
        np.ones(5),
        [],
        bank_max=math.radians(80.0),
        path_limits=False,
        virtual_control=False,
        weight_trust_region=0.005,
        weight_regularization=0.0,
        weight_virtual_control=1e4,
        weight_control_smoothness=0.7,
    )
    data = SubproblemData(
        x_ref=np.ones((K, 5)),
        u_ref=u_ref,
        f=np.zeros((K, 5)),
        A=np.zeros((K, 5, 5)),
        B=np.zeros((K, 5, 2)),
        cost_gradient=np.zeros((K, 5)),
        terminal_gradient=np.zeros(5),
        radius_lower=None,
        x0=np.ones(5),
        bank_step_max=np.full(K - 1, math.radians(90.0)),
    )
    cone = tr.build(data)
    z = np.zeros(tr.n)
    z[tr.col_u] = u_ref
    P = cone.P.toarray()
    P = P + np.triu(P, 1).T  # stored upper triangular
    gradient = P @ z + cone.q
    assert np.max(np.abs(gradient[tr.col_u])) <= 1e-12
