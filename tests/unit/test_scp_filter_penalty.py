"""Paper 003's globalization pieces: the non-monotone filter (eqs. 74-75), the oscillation test
(eq. 61) and the variable quadratic penalty (Remark 2, eqs. 77-79, and the line-search rule).

Pure logic on given numbers: exact comparisons, no tolerance beyond float rounding.
"""

from __future__ import annotations

import pytest

from worker.solver.scp.filter import NonMonotoneFilter
from worker.solver.scp.penalty import WEIGHT_MAX, VariableQuadraticPenalty, oscillating


def test_filter_accepts_a_decrease_of_either_measure_and_rejects_a_dominated_point() -> None:
    f = NonMonotoneFilter(zeta_c=0.1, zeta_f=0.1, memory=1)
    f.start(1.0, 10.0)
    assert f.acceptable(0.5, 12.0)  # violation down by more than zeta_c: accepted
    assert f.acceptable(1.5, 8.0)  # objective down by more than zeta_f * c: accepted
    assert not f.acceptable(0.95, 9.95)  # neither decrease is sufficient
    f.accept(0.5, 12.0)
    # the envelope of the accepted point's references: (0.9, 9.95) now dominates
    assert f.dominated(0.95, 10.0)
    assert not f.acceptable(0.92, 9.99)
    assert f.acceptable(0.3, 11.9)


def test_filter_is_non_monotone_within_its_memory() -> None:
    """With a memory of 3 the reference objective is the largest of the last three accepted:
    a point above the last one but below that maximum (minus the margin) is acceptable."""
    f = NonMonotoneFilter(zeta_c=0.1, zeta_f=0.0, memory=3)
    f.start(1.0, 5.0)
    f.accept(1.0, 3.0)
    f.accept(1.0, 2.0)
    assert f.acceptable(1.0, 4.0)  # above 2 and 3, below the 5 still remembered
    f.accept(1.0, 1.0)  # the 5 leaves the memory: the reference is now 3
    assert not f.acceptable(1.0, 4.0)
    assert f.acceptable(1.0, 2.5)


def test_filter_refuses_beyond_the_largest_admissible_violation() -> None:
    f = NonMonotoneFilter(c_max=2.0)
    f.start(1.0, 0.0)
    assert not f.acceptable(2.0, -100.0)
    assert f.acceptable(0.5, 0.0)


@pytest.mark.parametrize(
    ("costs", "expected"),
    [
        ([4.0, 5.0, 3.0, 3.5], True),  # up, down, up: eq. 61
        ([5.0, 4.0, 3.0, 2.0], False),  # monotone descent
        ([4.0, 5.0, 6.0, 7.0], False),
        ([1.0, 2.0, 1.5], False),  # fewer than four values
    ],
)
def test_oscillation_test_of_eq_61(costs: list[float], expected: bool) -> None:
    assert oscillating(costs) is expected


def test_penalty_starts_hard_and_switches_on_oscillation_at_weight_one() -> None:
    p = VariableQuadraticPenalty(initial_weight=1.0)
    for cost in (4.0, 5.0, 3.0):
        p.observe(cost, 1.0, 1.0)
        assert p.hard and p.weight == 0.0
    p.observe(3.5, 1.0, 1.0)
    assert not p.hard and p.weight == 1.0


def test_line_search_rule_halves_after_a_whole_descending_step_and_doubles_otherwise() -> None:
    p = VariableQuadraticPenalty(initial_weight=1.0, stage="penalty", weight=1.0)
    p.costs = [10.0]
    p.observe(9.0, 1.0, 1.0, full_step=True)
    assert p.weight == 0.5
    p.observe(9.5, 1.0, 1.0, full_step=True)  # the objective rose
    assert p.weight == 1.0
    p.observe(9.0, 1.0, 1.0, full_step=False)  # a shortened step
    assert p.weight == 2.0


def test_direction_history_rule_follows_eqs_77_to_79_within_a_decade_per_iteration() -> None:
    p = VariableQuadraticPenalty(
        initial_weight=1.0, rule="direction_history", stage="penalty", weight=1.0
    )
    p.steps = [4.0]
    p.observe(10.0, 2.0, 1.0)  # e = 0.5; theta starts so that w stays 1
    assert p.theta == pytest.approx(2.0)
    assert p.weight == pytest.approx(1.0)
    p.observe(9.0, 0.5, 1.0)  # e = 0.25: theta = 2 * 0.25 / 0.5 = 1, w = theta |g| / |d| = 2
    assert p.theta == pytest.approx(1.0)
    assert p.weight == pytest.approx(2.0)
    p.observe(8.0, 0.001, 1.0)  # w would be 1 * 0.002 / 0.25 ... capped at a decade per step
    assert p.weight <= 20.0


def test_an_unsolvable_subproblem_makes_the_weight_ten_times_heavier() -> None:
    p = VariableQuadraticPenalty(initial_weight=1.0, stage="penalty", weight=3.0)
    p.infeasible()
    assert p.weight == 30.0
    p.weight = WEIGHT_MAX
    p.infeasible()
    assert p.weight == WEIGHT_MAX
