"""The relaxed weights of the energy method: the trust-region weight (``RelaxingTrustWeight``)
and the per-node cone-tightness regularization (``ConeRegularization``). Pure logic: exact
figures."""

from __future__ import annotations

import numpy as np

from worker.solver.methods.energy_scp.regularization import ConeRegularization
from worker.solver.scp.trust import RelaxingTrustWeight


def test_trust_weight_held_then_relaxed_to_its_floor() -> None:
    trust = RelaxingTrustWeight(initial=1e-2, minimum=1e-4, factor=0.1, hold=2)
    step = np.array([1.0, 0.0])
    trust.after_iteration(1, step)
    assert trust.weight == 1e-2 and not trust.relaxed  # held
    trust.after_iteration(2, step)
    assert np.isclose(trust.weight, 1e-3) and not trust.relaxed
    trust.after_iteration(3, step)
    trust.after_iteration(4, step)
    assert np.isclose(trust.weight, 1e-4) and trust.relaxed  # floored, not below


def test_trust_weight_stiffens_after_a_swing_back_and_stays_relaxed() -> None:
    trust = RelaxingTrustWeight(initial=1.0, minimum=1e-2, factor=0.1, hold=0)
    trust.after_iteration(0, np.array([1.0, 0.0]))
    trust.after_iteration(1, np.array([1.0, 0.1]))
    assert np.isclose(trust.weight, 1e-2) and trust.relaxed
    trust.after_iteration(2, np.array([-1.0, 0.0]))  # the step swings back: 1 / factor^2
    assert np.isclose(trust.weight, 1.0)
    assert trust.relaxed  # the floor was reached once: a small step now is a stationary one


def test_a_rejected_step_undoes_two_relaxations_and_raises_the_floor_above_its_weight() -> None:
    trust = RelaxingTrustWeight(initial=1.0, minimum=1e-6, factor=0.25, hold=0)
    for k in range(3):
        trust.after_iteration(k, np.array([1.0, 0.0]))
    assert np.isclose(trust.weight, 0.25**3)
    assert trust.rejected()  # 0.25**3 made a step the linearization did not hold
    assert np.isclose(trust.weight, 0.25) and np.isclose(trust.floor, 0.25**2)
    assert not trust.relaxed
    for k in range(3, 6):
        trust.after_iteration(k, np.array([1.0, 0.0]))
    assert np.isclose(trust.weight, 0.25**2) and trust.relaxed  # never back to 0.25**3
    fixed = RelaxingTrustWeight(initial=5e-3, minimum=1e-5, factor=1.0, hold=0)
    assert not fixed.rejected()
    assert fixed.weight == 5e-3  # the paper's fixed weight stays fixed


def test_factor_one_keeps_the_paper_weight_and_counts_as_relaxed() -> None:
    trust = RelaxingTrustWeight(initial=5e-3, minimum=1e-5, factor=1.0, hold=0)
    trust.after_iteration(3, np.ones(3))
    assert trust.weight == 5e-3 and trust.relaxed


def test_regularization_lightens_on_the_circle_and_keeps_nodes_that_fell_inside() -> None:
    reg = ConeRegularization(nodes=3, weight=1000.0, minimum=100.0, hold=1)
    on_circle = np.array([[1.0, 0.0], [0.0, 1.0], [0.6, 0.8]])
    reg.after_iteration(0, on_circle)
    assert np.array_equal(reg.weights, [1000.0] * 3)  # held
    inside = on_circle.copy()
    inside[1] *= 0.5
    reg.after_iteration(1, inside)
    assert np.array_equal(reg.weights, [500.0, 1000.0, 500.0])  # node 1 capped at the full
    for it in range(2, 6):
        reg.after_iteration(it, on_circle)
    # floored at the minimum on the circle; node 1 keeps its weight once it was needed
    assert np.array_equal(reg.weights, [100.0, 1000.0, 100.0])
