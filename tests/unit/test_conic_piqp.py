"""The PIQP backend against Clarabel: the same optimum and multipliers on quadratic programs,
its solver reused while the pattern stays, and Clarabel for cones and for what PIQP does not
solve."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from tests.unit.test_conic import _infeasible_problem, _random_socp, _stalled
from worker.solver.conic import (
    ClarabelBackend,
    ConeProblem,
    ConeSpec,
    ConicStatus,
    PiqpBackend,
    make_backend,
)

COST_RTOL = 1e-6
"""Both interior-point solvers stop at gaps and residuals of about 1e-8 (their defaults), so
two optimal costs agree far inside 1e-6 relative."""
STATIONARITY_ATOL = 1e-6
"""P x + q + A'y at PIQP's point and multipliers: its dual residual tolerance is 1e-8 absolute
(plus 1e-9 relative to the data); 1e-6 leaves room for the data's size."""


def _random_qp(seed: int) -> ConeProblem:
    """A strictly feasible QP (equalities and inequalities, no cones) with a definite P."""
    rng = np.random.default_rng(seed)
    return _random_socp(rng, n=14, n_zero=4, n_nonneg=9, soc_dims=())


def _stationarity(problem: ConeProblem, x: np.ndarray, y: np.ndarray) -> float:
    """The largest entry of P x + q + A'y (P holds its upper triangle)."""
    assert problem.P is not None
    full = problem.P + sp.triu(problem.P, 1).T
    return float(np.max(np.abs(full @ x + problem.q + problem.A.T @ y)))


def test_piqp_agrees_with_clarabel_and_its_multipliers_are_clarabels() -> None:
    """Cost, point and multipliers (Clarabel's sign: y >= 0 on the inequality rows)."""
    for seed in range(5):
        problem = _random_qp(seed)
        ours = PiqpBackend().solve(problem)
        theirs = ClarabelBackend().solve(problem)
        assert ours.status == ConicStatus.OPTIMAL and ours.solver == "piqp"
        assert ours.x is not None and ours.y is not None and ours.objective is not None
        assert theirs.x is not None and theirs.objective is not None and theirs.y is not None
        assert np.isclose(ours.objective, theirs.objective, rtol=COST_RTOL, atol=1e-9)
        np.testing.assert_allclose(ours.x, theirs.x, rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(ours.y, theirs.y, rtol=1e-5, atol=1e-6)
        assert _stationarity(problem, ours.x, ours.y) < STATIONARITY_ATOL
        assert np.all(ours.y[problem.cones.n_zero :] >= -1e-9)


def test_a_repeated_pattern_updates_the_solver_and_matches_a_fresh_one() -> None:
    """New values on the same pattern: an update, the same answer as a fresh setup."""
    first = _random_qp(11)
    rng = np.random.default_rng(12)
    second = _random_socp(rng, n=14, n_zero=4, n_nonneg=9, soc_dims=(), A_pattern=first.A)
    assert first.P is not None
    second.P = first.P.copy()
    second.P.data = first.P.data * 1.5
    backend = PiqpBackend()
    backend.solve(first)
    reused = backend.solve(second)
    fresh = PiqpBackend().solve(second)
    assert (backend.setups, backend.updates) == (1, 1)
    assert reused.x is not None and fresh.x is not None
    np.testing.assert_allclose(reused.x, fresh.x, rtol=1e-6, atol=1e-8)


def test_a_recorded_foh_subproblem_solves_as_with_clarabel() -> None:
    """The foh-ptr subproblem on which a fresh Clarabel at its defaults stalls (soft-terminal
    weights of 3e6 beside unit ones): PIQP solves it feasible (rows to 1e-9) and stationary, at
    a cost no higher than Clarabel's robust retry. That retry (static regularization 1e-7) ends
    with a stationarity residual of about 1e-4 and a cost 8e-6 higher, so the costs are held to
    1e-4 relative, not COST_RTOL."""
    problem = _stalled()
    ours = PiqpBackend().solve(problem)
    theirs = ClarabelBackend().solve(problem)
    assert ours.solver == "piqp" and ours.status == ConicStatus.OPTIMAL
    assert theirs.status == ConicStatus.OPTIMAL
    assert ours.x is not None and ours.y is not None
    assert ours.objective is not None and theirs.objective is not None
    rows = problem.b - problem.A @ ours.x
    n_zero = problem.cones.n_zero
    assert np.max(np.abs(rows[:n_zero])) < 1e-9 and np.min(rows[n_zero:]) > -1e-9
    assert _stationarity(problem, ours.x, ours.y) < STATIONARITY_ATOL
    assert ours.objective <= theirs.objective + COST_RTOL * abs(theirs.objective)
    assert np.isclose(ours.objective, theirs.objective, rtol=1e-4)


def test_a_problem_with_cones_goes_to_clarabel() -> None:
    problem = _random_socp(np.random.default_rng(3))
    backend = PiqpBackend()
    answer = backend.solve(problem)
    assert answer.solver == "clarabel" and answer.status == ConicStatus.OPTIMAL
    assert (backend.setups, backend.fallbacks) == (0, 0)


def test_what_piqp_does_not_solve_is_solved_again_by_clarabel() -> None:
    """An infeasible QP: PIQP's verdict is checked by Clarabel, which answers, and counted."""
    backend = PiqpBackend()
    answer = backend.solve(_infeasible_problem())
    assert answer.status == ConicStatus.INFEASIBLE
    assert answer.solver == "piqp>clarabel" and backend.fallbacks == 1


def test_a_qp_without_inequalities_or_equalities() -> None:
    """Empty row groups: only equalities, then only inequalities."""
    P = sp.csc_matrix(np.eye(2))
    q = np.array([-1.0, -2.0])
    only_eq = ConeProblem(P, q, sp.csc_matrix(np.array([[1.0, 1.0]])), np.array([1.0]),
                          ConeSpec(1, 0))  # fmt: skip
    only_ineq = ConeProblem(P, q, sp.csc_matrix(np.eye(2)), np.array([0.5, 0.5]), ConeSpec(0, 2))
    for problem, expected in ((only_eq, [0.0, 1.0]), (only_ineq, [0.5, 0.5])):
        answer = PiqpBackend().solve(problem)
        assert answer.status == ConicStatus.OPTIMAL and answer.x is not None
        np.testing.assert_allclose(answer.x, expected, atol=1e-7)


def test_the_registry_makes_it() -> None:
    assert isinstance(make_backend("piqp"), PiqpBackend)
