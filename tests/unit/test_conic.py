"""Unit tests of the conic layer: problem validation, sparse assembly, status maps and backends."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import clarabel
import numpy as np
import pytest
import scipy.sparse as sp

from worker.solver.conic import (
    KNOWN_BACKENDS,
    ClarabelBackend,
    ConeProblem,
    ConeSpec,
    ConicSolution,
    ConicStatus,
    CvxpyBackend,
    FallbackBackend,
    SparseAssembler,
    make_backend,
    map_clarabel_status,
    map_cvxpy_status,
    same_pattern,
)
from worker.solver.conic.clarabel_direct import clarabel_cones

# Both backends run interior-point methods to a relative/absolute duality gap of about 1e-8
# (Clarabel's and ECOS's defaults), so two optimal costs agree far inside 1e-6 relative.
COST_RTOL = 1e-6


def _random_socp(
    rng: np.random.Generator,
    *,
    n: int = 12,
    n_zero: int = 3,
    n_nonneg: int = 4,
    soc_dims: tuple[int, ...] = (3, 4, 3, 5),
    A_pattern: sp.csc_matrix | None = None,
) -> ConeProblem:
    """Strictly feasible SOCP with a positive definite P: b = A x0 + s with s inside K."""
    spec = ConeSpec(n_zero, n_nonneg, soc_dims)
    m = spec.n_rows
    if A_pattern is None:
        A = sp.random(m, n, density=0.4, random_state=rng, format="csc")
    else:
        A = A_pattern.copy()
        A.data = rng.standard_normal(A.nnz)
    x0 = rng.standard_normal(n)
    s = np.zeros(m)
    s[n_zero : n_zero + n_nonneg] = rng.uniform(0.1, 1.0, n_nonneg)
    for start, d in zip(spec.soc_starts(), soc_dims, strict=True):
        tail = rng.standard_normal(d - 1)
        s[start] = np.linalg.norm(tail) + rng.uniform(0.1, 1.0)
        s[start + 1 : start + d] = tail
    M = rng.standard_normal((n, n))
    P = sp.triu(M @ M.T + 0.1 * np.eye(n), format="csc")
    return ConeProblem(P=P, q=rng.standard_normal(n), A=A, b=A @ x0 + s, cones=spec)


def _unit_ball_problem(q: np.ndarray) -> ConeProblem:
    """minimize q'x subject to ||x|| <= 1: s = (1, x) = b - A x with A = [0; -I], b = (1, 0)."""
    n = q.size
    A = sp.vstack([sp.csr_matrix((1, n)), -sp.eye(n)], format="csc")
    b = np.zeros(n + 1)
    b[0] = 1.0
    return ConeProblem(P=None, q=q, A=A, b=b, cones=ConeSpec(0, 0, (n + 1,)))


def _infeasible_problem() -> ConeProblem:
    """x0 = 1 (equality) and x0 <= 0 (nonnegative row): no feasible point."""
    A = sp.csc_matrix(np.array([[1.0, 0.0], [1.0, 0.0]]))
    P = sp.csc_matrix(np.eye(2))
    return ConeProblem(P=P, q=np.zeros(2), A=A, b=np.array([1.0, 0.0]), cones=ConeSpec(1, 1))


# --- problem data and validation -------------------------------------------------------------


def test_cone_spec_rows_and_soc_starts() -> None:
    spec = ConeSpec(2, 3, (3, 7, 3))
    assert spec.n_rows == 2 + 3 + 13
    assert spec.soc_starts().tolist() == [5, 8, 15]
    assert ConeSpec(1, 0).soc_starts().tolist() == []


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda p: setattr(p, "b", p.b[:-1]), "A has shape"),
        (lambda p: setattr(p, "q", p.q[:, None]), "q must be 1-D"),
        (lambda p: setattr(p, "A", p.A.tocsr()), "CSC"),
        (lambda p: setattr(p, "P", sp.csc_matrix(p.P.T)), "upper triangle"),
        (lambda p: setattr(p, "cones", ConeSpec(3, 5, (3, 4, 3, 5))), "cones cover"),
        (lambda p: setattr(p, "cones", ConeSpec(3, 4, (3, 4, 3, 1, 4))), "dimension >= 2"),
        (lambda p: p.q.__setitem__(0, np.nan), "non-finite"),
    ],
)
def test_validate_rejects_bad_problems(mutate: object, message: str) -> None:
    problem = _random_socp(np.random.default_rng(1))
    problem.validate()
    mutate(problem)  # type: ignore[operator]
    with pytest.raises(ValueError, match=message):
        problem.validate()


# --- SparseAssembler ---------------------------------------------------------------------------


def test_assembler_matches_scipy_and_keeps_pattern() -> None:
    rng = np.random.default_rng(2)
    shape = (30, 20)
    rows = rng.integers(0, shape[0], 400)  # 400 triplets in 600 cells: many duplicates
    cols = rng.integers(0, shape[1], 400)
    assembler = SparseAssembler(rows, cols, shape)

    values = rng.standard_normal(rows.size)
    got = assembler.assemble(values)
    want = sp.coo_matrix((values, (rows, cols)), shape=shape).tocsc()
    want.sum_duplicates()
    assert got.format == "csc"
    assert got.nnz == want.nnz == assembler.nnz
    assert np.array_equal(got.indptr, want.indptr)
    assert np.array_equal(got.indices, want.indices)
    # Exact summation order can differ from scipy's; 1e-12 covers rounding of a few additions.
    np.testing.assert_allclose(got.data, want.data, rtol=0, atol=1e-12)

    zeros = rng.standard_normal(rows.size)
    zeros[::2] = 0.0
    zeros[rows == rows[1]] = 0.0  # every triplet of some cells is zero: the entry must stay
    second = assembler.assemble(zeros)
    assert same_pattern(second, got)
    assert second.nnz == got.nnz
    dense = sp.coo_matrix((zeros, (rows, cols)), shape=shape).toarray()
    np.testing.assert_allclose(second.toarray(), dense, rtol=0, atol=1e-12)


def test_assembler_without_duplicates_is_a_permutation() -> None:
    rows = np.array([2, 0, 1, 0])
    cols = np.array([0, 1, 1, 0])
    assembler = SparseAssembler(rows, cols, (3, 2))
    matrix = assembler.assemble([1.0, 2.0, 3.0, 4.0])
    np.testing.assert_array_equal(matrix.toarray(), [[4.0, 2.0], [0.0, 3.0], [1.0, 0.0]])


def test_assembler_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match="below the diagonal"):
        SparseAssembler([1], [0], (2, 2), upper_triangular=True)
    with pytest.raises(ValueError, match="out of bounds"):
        SparseAssembler([2], [0], (2, 2))
    assembler = SparseAssembler([0, 1], [0, 1], (2, 2), upper_triangular=True)
    with pytest.raises(ValueError, match="expected 2 values"):
        assembler.assemble([1.0])


# --- status maps -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("raw", "expected"),
    [
        ("Solved", ConicStatus.OPTIMAL),
        ("AlmostSolved", ConicStatus.INACCURATE),
        ("PrimalInfeasible", ConicStatus.INFEASIBLE),
        ("DualInfeasible", ConicStatus.INFEASIBLE),
        ("AlmostPrimalInfeasible", ConicStatus.INFEASIBLE),
        ("AlmostDualInfeasible", ConicStatus.INFEASIBLE),
        ("MaxIterations", ConicStatus.NUMERICAL_ERROR),
        ("MaxTime", ConicStatus.TIME_LIMIT),
        ("NumericalError", ConicStatus.NUMERICAL_ERROR),
        ("InsufficientProgress", ConicStatus.NUMERICAL_ERROR),
        ("Unsolved", ConicStatus.NUMERICAL_ERROR),
        ("CallbackTerminated", ConicStatus.TIME_LIMIT),
        ("SolverStatus.Solved", ConicStatus.OPTIMAL),
        ("SomethingNew", ConicStatus.NUMERICAL_ERROR),
    ],
)
def test_clarabel_status_map(raw: str, expected: ConicStatus) -> None:
    assert map_clarabel_status(raw) is expected


def test_clarabel_status_map_accepts_enum_objects() -> None:
    clarabel = pytest.importorskip("clarabel")
    assert map_clarabel_status(clarabel.SolverStatus.MaxTime) is ConicStatus.TIME_LIMIT


@pytest.mark.parametrize(
    ("raw", "expected"),
    [
        ("optimal", ConicStatus.OPTIMAL),
        ("optimal_inaccurate", ConicStatus.INACCURATE),
        ("infeasible", ConicStatus.INFEASIBLE),
        ("infeasible_inaccurate", ConicStatus.INFEASIBLE),
        ("unbounded", ConicStatus.INFEASIBLE),
        ("unbounded_inaccurate", ConicStatus.INFEASIBLE),
        ("user_limit", ConicStatus.TIME_LIMIT),
        ("solver_error", ConicStatus.NUMERICAL_ERROR),
        ("brand_new_status", ConicStatus.NUMERICAL_ERROR),
        (None, ConicStatus.NUMERICAL_ERROR),
    ],
)
def test_cvxpy_status_map(raw: str | None, expected: ConicStatus) -> None:
    assert map_cvxpy_status(raw) is expected


def test_usable_statuses() -> None:
    assert {s for s in ConicStatus if s.usable} == {ConicStatus.OPTIMAL, ConicStatus.INACCURATE}


# --- backends on real problems ----------------------------------------------------------------


def test_random_socp_backends_agree() -> None:
    problem = _random_socp(np.random.default_rng(3))
    direct = ClarabelBackend().solve(problem)
    assert direct.status is ConicStatus.OPTIMAL
    assert direct.x is not None and direct.objective is not None
    assert direct.solver == "clarabel" and direct.iterations > 0
    # Equality rows hold to the solver's feasibility tolerance (1e-8, scaled by |b| ~ 10).
    residual = problem.A[: problem.cones.n_zero] @ direct.x - problem.b[: problem.cones.n_zero]
    assert np.max(np.abs(residual)) < 1e-6
    for solver in ("CLARABEL", "ECOS"):
        other = CvxpyBackend(solver).solve(problem)
        assert other.status is ConicStatus.OPTIMAL, solver
        assert other.solver == f"cvxpy:{solver}"
        assert other.objective == pytest.approx(direct.objective, rel=COST_RTOL), solver


def test_diagonal_psd_objective_agrees_with_ecos() -> None:
    # Diagonal P takes the sum-of-squares route for ECOS; one zero entry (with zero cost) keeps
    # the objective bounded while exercising the skipped-variable branch.
    problem = _random_socp(np.random.default_rng(7))
    diagonal = np.linspace(0.0, 2.0, problem.n)
    problem.P = sp.csc_matrix(sp.diags(diagonal))
    problem.q[0] = 0.0
    direct = ClarabelBackend().solve(problem)
    ecos = CvxpyBackend("ECOS").solve(problem)
    assert direct.status is ecos.status is ConicStatus.OPTIMAL
    assert ecos.objective == pytest.approx(direct.objective, rel=COST_RTOL)


def test_multipliers_satisfy_stationarity_and_backends_agree() -> None:
    """P x + q + A'y = 0 with y >= 0 on the inequality rows (Clarabel's sign), from both
    backends, on a QP whose optimum has an active inequality and an equality."""
    P = sp.triu(sp.csc_matrix(np.diag([2.0, 1.0, 3.0])), format="csc")
    q = np.array([1.0, -3.0, 0.5])
    A = sp.csc_matrix(np.array([[1.0, 1.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]))
    b = np.array([1.0, 0.8, 10.0])  # x0 + x1 + x2 = 1, x1 <= 0.8 (active), -x0 <= 10
    problem = ConeProblem(P=P, q=q, A=A, b=b, cones=ConeSpec(1, 2))
    found = []
    for backend in (ClarabelBackend(), CvxpyBackend("CLARABEL")):
        solution = backend.solve(problem)
        assert solution.x is not None and solution.y is not None
        stationarity = P @ solution.x + q + A.T @ solution.y
        # Interior-point tolerance 1e-8 on the gap and residuals; 1e-6 leaves room.
        assert np.max(np.abs(stationarity)) < 1e-6
        assert solution.y[1] > 0.1 and solution.y[2] >= -1e-8  # active and inactive rows
        found.append(solution.y)
    np.testing.assert_allclose(found[0], found[1], atol=1e-6)


def test_linear_objective_on_unit_ball() -> None:
    q = np.array([3.0, -4.0, 0.0])
    problem = _unit_ball_problem(q)
    for backend in (ClarabelBackend(), CvxpyBackend("CLARABEL")):
        solution = backend.solve(problem)
        assert solution.status is ConicStatus.OPTIMAL
        assert solution.x is not None and solution.objective is not None
        # Analytic optimum: x = -q/|q|, cost -|q| = -5; 1e-6 is far above the 1e-8 IPM gap.
        assert solution.objective == pytest.approx(-5.0, rel=COST_RTOL)
        np.testing.assert_allclose(solution.x, -q / 5.0, atol=1e-6)


@pytest.mark.parametrize("backend_name", ["clarabel", "cvxpy:CLARABEL", "cvxpy:ECOS"])
def test_infeasible_problem(backend_name: str) -> None:
    solution = make_backend(backend_name).solve(_infeasible_problem())
    assert solution.status is ConicStatus.INFEASIBLE
    assert solution.x is None and solution.objective is None


def test_data_update_matches_fresh_solves() -> None:
    rng = np.random.default_rng(4)
    first = _random_socp(rng)
    second = _random_socp(rng, A_pattern=first.A)
    assert same_pattern(first.A, second.A) and same_pattern(first.P, second.P)

    reused = ClarabelBackend()
    answers = [reused.solve(first), reused.solve(second)]
    assert (reused.setups, reused.updates) == (1, 1)
    for problem, answer in zip((first, second), answers, strict=True):
        fresh = ClarabelBackend().solve(problem)
        assert answer.status is fresh.status is ConicStatus.OPTIMAL
        assert answer.objective == pytest.approx(fresh.objective, rel=COST_RTOL)
        # P is positive definite (smallest eigenvalue ~0.1 for this seed), so the minimizer is
        # unique: a cost gap of ~1e-8 * |cost| (~5e-7) bounds |x - x*| by sqrt(2 gap / 0.1) ~ 3e-3.
        assert answer.x is not None and fresh.x is not None
        np.testing.assert_allclose(answer.x, fresh.x, rtol=0, atol=3e-3)


def test_pattern_change_rebuilds_solver() -> None:
    rng = np.random.default_rng(5)
    backend = ClarabelBackend()
    backend.solve(_random_socp(rng))
    other = _random_socp(rng)  # new random A: a different pattern
    solution = backend.solve(other)
    assert solution.status is ConicStatus.OPTIMAL
    assert (backend.setups, backend.updates) == (2, 0)
    no_reuse = ClarabelBackend(reuse=False)
    no_reuse.solve(other)
    no_reuse.solve(other)
    assert (no_reuse.setups, no_reuse.updates) == (2, 0)


def test_tiny_time_limit_maps_to_time_limit() -> None:
    # Clarabel checks its clock at the end of iteration 0; any real solve has used more than
    # 1e-9 s by then, so MaxTime is certain even for a small problem.
    problem = _random_socp(np.random.default_rng(6))
    backend = ClarabelBackend()
    limited = backend.solve(problem, time_limit_s=1e-9)
    assert limited.status is ConicStatus.TIME_LIMIT
    assert limited.raw_status == "MaxTime" and limited.x is None
    # The limit is per call: the reused solver runs unlimited again.
    assert backend.solve(problem).status is ConicStatus.OPTIMAL
    assert backend.setups == 1
    assert (
        CvxpyBackend("CLARABEL").solve(problem, time_limit_s=1e-9).status is ConicStatus.TIME_LIMIT
    )


# --- factory and fallback ------------------------------------------------------------------------


def test_make_backend_names() -> None:
    assert make_backend("clarabel").name == "clarabel"
    assert make_backend("cvxpy").name == "cvxpy:CLARABEL"
    assert make_backend("cvxpy:ecos").name == "cvxpy:ECOS"
    wrapped = make_backend("clarabel", fallback="SCS")
    assert isinstance(wrapped, FallbackBackend)
    assert wrapped.fallback.name == "cvxpy:SCS"
    assert make_backend("clarabel", fallback="cvxpy:ECOS").name == "clarabel>cvxpy:ECOS"


@pytest.mark.parametrize("name", ["gurobi", "cvxpy:OSQP", "Clarabel", ""])
def test_make_backend_rejects_unknown(name: str) -> None:
    with pytest.raises(ValueError, match="known: ") as info:
        make_backend(name)
    for known in KNOWN_BACKENDS:
        assert known in str(info.value)


def _solution(status: ConicStatus, solver: str) -> ConicSolution:
    """A minimal solution record with the given status, as a fake backend would return."""
    x = np.zeros(2) if status.usable else None
    return ConicSolution(
        x=x,
        status=status,
        raw_status=str(status),
        objective=0.0 if status.usable else None,
        solve_time_s=0.5,
        iterations=3,
        setup_time_s=0.25,
        solver=solver,
    )


@dataclass
class _FakeBackend:
    """Returns a fixed status and records the time limits it was called with."""

    name: str
    status: ConicStatus
    calls: list[float | None] = field(default_factory=list)

    def solve(self, problem: ConeProblem, *, time_limit_s: float | None = None) -> ConicSolution:
        self.calls.append(time_limit_s)
        return _solution(self.status, self.name)


def test_fallback_resolves_after_numerical_error() -> None:
    primary = _FakeBackend("primary", ConicStatus.NUMERICAL_ERROR)
    backup = _FakeBackend("backup", ConicStatus.OPTIMAL)
    result = FallbackBackend(primary, backup).solve(_infeasible_problem(), time_limit_s=100.0)
    assert result.solver == "backup" and result.status is ConicStatus.OPTIMAL
    assert len(primary.calls) == len(backup.calls) == 1
    assert backup.calls[0] is not None and 0.0 < backup.calls[0] <= 100.0  # remaining budget
    assert result.solve_time_s == pytest.approx(1.0) and result.setup_time_s == pytest.approx(0.5)


def test_fallback_skipped_when_primary_is_fine_or_conclusive() -> None:
    for status in (ConicStatus.OPTIMAL, ConicStatus.INFEASIBLE, ConicStatus.TIME_LIMIT):
        primary = _FakeBackend("primary", status)
        backup = _FakeBackend("backup", ConicStatus.OPTIMAL)
        result = FallbackBackend(primary, backup).solve(_infeasible_problem())
        assert result.solver == "primary" and backup.calls == []


def test_fallback_keeps_inaccurate_primary_when_backup_is_worse() -> None:
    primary = _FakeBackend("primary", ConicStatus.INACCURATE)
    backup = _FakeBackend("backup", ConicStatus.NUMERICAL_ERROR)
    result = FallbackBackend(primary, backup).solve(_infeasible_problem())
    assert len(backup.calls) == 1
    assert result.solver == "primary" and result.status is ConicStatus.INACCURATE


def test_fallback_not_run_without_time_left() -> None:
    primary = _FakeBackend("primary", ConicStatus.NUMERICAL_ERROR)
    backup = _FakeBackend("backup", ConicStatus.OPTIMAL)
    result = FallbackBackend(primary, backup).solve(_infeasible_problem(), time_limit_s=0.0)
    assert result.solver == "primary" and backup.calls == []


class _StallingOnUpdate(ClarabelBackend):
    """A real Clarabel backend whose first data-update solve reports a stall (as a reused
    solver's stale equilibration does on some SCP subproblems); fresh setups solve normally."""

    def __init__(self) -> None:
        super().__init__()
        self.stalled = 0

    def _solve_once(self, problem: ConeProblem, time_limit_s: float | None) -> ConicSolution:
        updates = self.updates
        solution = super()._solve_once(problem, time_limit_s)
        if self.updates > updates and not self.stalled:
            self.stalled += 1
            return replace(
                solution, status=ConicStatus.NUMERICAL_ERROR, raw_status="InsufficientProgress"
            )
        return solution


def test_reused_solver_in_trouble_is_rebuilt_once() -> None:
    rng = np.random.default_rng(4)
    first = _random_socp(rng)
    second = _random_socp(rng, A_pattern=first.A)
    backend = _StallingOnUpdate()
    backend.solve(first)
    answer = backend.solve(second)
    # the update stalled, the rebuilt solver answered: one more setup, both attempts' times kept
    assert backend.stalled == 1 and (backend.setups, backend.updates) == (2, 1)
    assert answer.status is ConicStatus.OPTIMAL and answer.raw_status == "Solved"
    fresh = ClarabelBackend().solve(second)
    assert answer.objective == pytest.approx(fresh.objective, rel=COST_RTOL)
    assert answer.iterations > fresh.iterations  # the stalled attempt's iterations are counted


def test_fresh_solver_in_trouble_is_not_retried() -> None:
    backend = ClarabelBackend(max_iter=1)  # stops after one interior-point iteration
    solution = backend.solve(_random_socp(np.random.default_rng(6)))
    assert solution.status is ConicStatus.NUMERICAL_ERROR
    assert (backend.setups, backend.updates) == (1, 0)


STALLED = Path(__file__).with_name("data") / "foh_free_time_stalled_subproblem.npz"
"""A foh-ptr subproblem of a free final time (user-problem suite 009, iteration 4 with
weight_trust_final_time 10) on which a fresh Clarabel at its defaults stalls: soft-terminal
weights of 3e6 beside unit ones."""


def _stalled() -> ConeProblem:
    d = np.load(STALLED)
    P = sp.csc_matrix((d["P_data"], d["P_indices"], d["P_indptr"]), shape=tuple(d["shape_P"]))
    A = sp.csc_matrix((d["A_data"], d["A_indices"], d["A_indptr"]), shape=tuple(d["shape_A"]))
    cones = ConeSpec(int(d["n_zero"]), int(d["n_nonneg"]), tuple(int(k) for k in d["soc_dims"]))
    return ConeProblem(P=P, q=d["q"], A=A, b=d["b"], cones=cones)


def test_a_fresh_solver_that_stalls_gets_the_robust_settings_once() -> None:
    problem = _stalled()
    plain = clarabel.DefaultSolver(
        problem.P,
        problem.q,
        problem.A,
        problem.b,
        clarabel_cones(problem.cones),
        _quiet_settings(),
    ).solve()
    assert str(plain.status) == "NumericalError"  # the premise, with the pinned Clarabel
    backend = ClarabelBackend()
    answer = backend.solve(problem)
    assert answer.status is ConicStatus.OPTIMAL and backend.setups == 2
    assert answer.iterations > plain.iterations  # the stalled attempt's iterations are counted
    # Another cure for the same stall (no equilibration) must give the same optimum: both are
    # interior-point solutions at gap 1e-8, the objective near -2.25, so 1e-5 relative.
    settings = _quiet_settings()
    settings.equilibrate_enable = False
    other = clarabel.DefaultSolver(
        problem.P, problem.q, problem.A, problem.b, clarabel_cones(problem.cones), settings
    ).solve()
    assert str(other.status) == "Solved"
    assert answer.objective == pytest.approx(other.obj_val, rel=1e-5)
    after = backend.solve(_random_socp(np.random.default_rng(6)))  # defaults again
    assert after.status is ConicStatus.OPTIMAL and backend._robust is False


def _quiet_settings() -> Any:
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    return settings
