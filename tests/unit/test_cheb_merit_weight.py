"""cheb-scvx's merit weight: a margin above the multipliers of the rows the subproblem relaxes,
read from the conic solution (reduced costs of the elastic columns; a terminal bound's two rows
by their difference), within the floor and the subproblem's own weight; and its stop on an
infeasibility that stalls."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from worker.solver.conic import ConeProblem, ConicSolution, ConicStatus
from worker.solver.conic.problem import ConeSpec
from worker.solver.methods.cheb_scvx.method import (
    MERIT_FLOOR,
    MERIT_MARGIN,
    STALL_ITERATIONS,
    ChebScvx,
    merit_weight_of,
)
from worker.solver.methods.cheb_scvx.subproblem import Columns

WEIGHT = 1000.0
# columns: 2 states, then 2 virtual controls, then 2 slacks (the second a terminal bound's)
COLS = Columns(y=0, u=2, t=2, nu=2, slack=4, n=6, terminal_rows=5)
# rows: 1 equality, then the 4 elastic bounds, 1 other row, the terminal bound's 2 rows
CONES = ConeSpec(n_zero=1, n_nonneg=7)


def _solution(y: np.ndarray | None) -> ConicSolution:
    return ConicSolution(np.zeros(6), ConicStatus.OPTIMAL, "Solved", 0.0, 0.0, 1, 0.0, "test", y=y)


def _problem() -> ConeProblem:
    return ConeProblem(None, np.zeros(6), sp.csc_matrix((8, 6)), np.zeros(8), CONES)


def _duals(reduced: list[float], other: float, terminal: tuple[float, float]) -> np.ndarray:
    return np.array([0.0, *reduced, other, *terminal])


def test_the_largest_multiplier_times_the_margin() -> None:
    # elastic multipliers 1000 - reduced cost: 4, 1, 2 (the terminal slack's column excluded)
    y = _duals([996.0, 999.0, 998.0, 0.0], other=500.0, terminal=(3.0, 2.5))
    weight = merit_weight_of(_solution(y), _problem(), COLS, WEIGHT, terminal=1)
    assert weight == MERIT_MARGIN * 4.0


def test_a_terminal_bound_counts_by_the_difference_of_its_rows() -> None:
    # on the central path both rows of a fixed value carry large multipliers; the bound's own
    # is their difference (here 10), not their sum (the slack's reduced cost says 1000 - 990)
    y = _duals([999.0, 999.0, 999.0, 10.0], other=0.0, terminal=(500.0, 490.0))
    weight = merit_weight_of(_solution(y), _problem(), COLS, WEIGHT, terminal=1)
    assert weight == MERIT_MARGIN * 10.0


def test_the_weight_stays_within_its_floor_and_the_subproblems() -> None:
    quiet = _duals([1000.0] * 4, other=0.0, terminal=(0.0, 0.0))
    assert merit_weight_of(_solution(quiet), _problem(), COLS, WEIGHT, 1) == MERIT_FLOOR * WEIGHT
    active = _duals([0.0, 1000.0, 1000.0, 1000.0], other=0.0, terminal=(0.0, 0.0))
    assert merit_weight_of(_solution(active), _problem(), COLS, WEIGHT, 1) == WEIGHT


def test_no_multipliers_keep_the_subproblems_weight() -> None:
    assert merit_weight_of(_solution(None), _problem(), COLS, WEIGHT, 1) == WEIGHT


class _Trail:
    """What ``ChebScvx.stalled`` reads of the method: its trail of infeasibilities."""

    def __init__(self) -> None:
        self.infeasibility_trail: list[float] = []


def _stalled_after(values: list[float], largest: float = 1.0) -> list[bool]:
    """Whether each accepted step of a run whose violation sums are ``values`` (their largest
    term ``largest``) ends it."""
    trail = _Trail()
    return [ChebScvx.stalled(trail, largest, v) is not None for v in values]  # type: ignore[arg-type]


def test_an_infeasibility_that_stops_moving_ends_the_run() -> None:
    flat = [50.0, 45.0] + [42.1387] * (STALL_ITERATIONS + 1)
    assert _stalled_after(flat) == [False] * (len(flat) - 1) + [True]


def test_a_moving_or_feasible_trail_goes_on() -> None:
    falling = [50.0 * 0.99**k for k in range(3 * STALL_ITERATIONS)]  # 1 % a step
    assert not any(_stalled_after(falling))
    # a sum that rises (a step that trades feasibility for the objective) has not stalled
    rising = [1.39, 1.0, 0.52, 0.066, 0.60, 0.48, 0.68, 0.73, 0.74, 0.67, 5.53]
    assert not any(_stalled_after(rising))
    feasible = [42.0] * (3 * STALL_ITERATIONS)  # the largest term within FEASIBLE: converging
    assert not any(_stalled_after(feasible, largest=5.0e-4))
