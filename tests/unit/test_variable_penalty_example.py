"""Paper 003's eq. 76 example run through the shared globalization (``scp.penalty`` and
``scp.filter``): minimize x1 subject to x1^2 + x2^2 = 1 from x = (0, 1.5), each subproblem the
linearized constraint with a box trust region of radius 0.5 and the quadratic penalty 0.5 w |d|^2.

Figure 8's three behaviours: with w = 0 (the hard trust region alone) the iterates oscillate and
never settle; with a very heavy weight each step is the shortest one onto the linearized
constraint, which converges to the feasible but non-optimal (0, 1); the variable penalty starts
hard, switches on oscillation (eq. 61) and, with the filter line search, reaches the optimum
(-1, 0). Tolerance 1e-6: the subproblems are solved by Clarabel to ~1e-9 and the outer
iteration converges quadratically near the optimum.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from worker.solver.conic import ConeProblem, ConeSpec, make_backend
from worker.solver.scp.filter import NonMonotoneFilter
from worker.solver.scp.penalty import VariableQuadraticPenalty, oscillating

RADIUS = 0.5
START = np.array([0.0, 1.5])
BACKEND = make_backend("clarabel")


def _step(x: np.ndarray, weight: float) -> np.ndarray:
    """min d1 + 0.5 w |d|^2 s.t. |x|^2 - 1 + 2 x.d = 0, |d_i| <= RADIUS."""
    P = sp.csc_matrix(np.eye(2) * weight) if weight > 0 else None
    q = np.array([1.0, 0.0])
    A = sp.csc_matrix(np.vstack([2.0 * x, np.eye(2), -np.eye(2)]))
    b = np.concatenate([[1.0 - x @ x], np.full(4, RADIUS)])
    solution = BACKEND.solve(ConeProblem(P, q, A, b, ConeSpec(1, 4)), time_limit_s=10.0)
    assert solution.x is not None
    return np.asarray(solution.x)


def _violation(x: np.ndarray) -> float:
    return abs(float(x @ x) - 1.0)


def test_the_hard_trust_region_alone_oscillates() -> None:
    x = START.copy()
    costs = []
    for _ in range(20):
        x = x + _step(x, 0.0)
        costs.append(float(x[0]))
    assert any(oscillating(costs[: i + 1]) for i in range(3, len(costs)))
    assert np.linalg.norm(x - np.array([-1.0, 0.0])) > 1e-2  # not at the optimum


def test_a_very_heavy_penalty_converges_to_the_wrong_feasible_point() -> None:
    """w = 1e6: the objective moves x1 by only -1/w per step, so 40 steps stay within 4e-5 of
    the feasible point closest to the start, (0, 1), far from the optimum."""
    x = START.copy()
    for _ in range(40):
        x = x + _step(x, 1.0e6)
    np.testing.assert_allclose(x, [0.0, 1.0], atol=1e-4)
    assert _violation(x) < 1e-8
    assert np.linalg.norm(x - np.array([-1.0, 0.0])) > 1.0


def test_the_variable_penalty_with_the_filter_reaches_the_optimum() -> None:
    x = START.copy()
    penalty = VariableQuadraticPenalty(initial_weight=1.0, minimum=1e-3)
    filt = NonMonotoneFilter(zeta_c=1e-4, zeta_f=1e-4, memory=4)
    filt.start(_violation(x), float(x[0]))
    for _ in range(60):
        d = _step(x, 0.0 if penalty.hard else penalty.weight)
        beta = 1.0
        while beta >= 1.0 / 64.0:
            trial = x + beta * d
            if filt.acceptable(_violation(trial), float(trial[0])):
                filt.accept(_violation(trial), float(trial[0]))
                break
            beta *= 0.5
        else:
            penalty.infeasible()
            penalty.stage = "penalty"
            continue
        x = trial
        penalty.observe(float(x[0]), float(np.linalg.norm(beta * d)), 1.0, beta == 1.0)
        if np.linalg.norm(beta * d) < 1e-10:
            break
    assert not penalty.hard  # the oscillation switched the stage
    np.testing.assert_allclose(x, [-1.0, 0.0], atol=1e-6)
