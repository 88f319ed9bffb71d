"""cvxpy backend: the same ConeProblem written as a cvxpy model and solved by a named conic solver.

Used to cross-check the direct Clarabel backend and as a fallback with a different solver.
cvxpy is imported on first use (the import alone takes about a second).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from time import perf_counter
from typing import Any

import numpy as np
import scipy.sparse as sp

from worker.solver.conic.base import CVXPY_SOLVERS, ConicSolution
from worker.solver.conic.problem import ConeProblem
from worker.solver.conic.status import ConicStatus, map_cvxpy_status

_NATIVE_QUADRATIC = frozenset({"CLARABEL", "SCS"})
"""Solvers that take 0.5 x'Px directly; for the others cvxpy factors P into cone constraints."""


def symmetric_from_upper(P_upper: sp.csc_matrix) -> sp.csc_matrix:
    """Full symmetric matrix from its upper triangle: U + U' - diag(U)."""
    return sp.csc_matrix(P_upper + P_upper.T - sp.diags(P_upper.diagonal()))


def _is_diagonal(P_upper: sp.csc_matrix) -> bool:
    """True when every stored entry of ``P_upper`` lies on the diagonal."""
    cols = np.repeat(np.arange(P_upper.shape[1]), np.diff(P_upper.indptr))
    return bool(np.all(P_upper.indices == cols))


class CvxpyBackend:
    """Solves ConeProblems through cvxpy with ``solver`` (CLARABEL, ECOS or SCS)."""

    def __init__(
        self, solver: str = "CLARABEL", *, solver_options: Mapping[str, Any] | None = None
    ) -> None:
        """Select the cvxpy solver; ``solver_options`` are passed on to ``Problem.solve``."""
        solver = solver.upper()
        if solver not in CVXPY_SOLVERS:
            raise ValueError(f"unsupported cvxpy solver {solver!r}; known: {CVXPY_SOLVERS}")
        self.solver = solver
        self.solver_options = dict(solver_options or {})
        self.name = f"cvxpy:{solver}"

    def _time_limit_options(self, time_limit_s: float | None) -> dict[str, Any]:
        """Solver-specific time limit keyword (ECOS has none, so it runs unlimited)."""
        if time_limit_s is None:
            return {}
        if self.solver == "CLARABEL":
            return {"time_limit": float(time_limit_s)}
        if self.solver == "SCS":
            return {"time_limit_secs": float(time_limit_s)}
        return {}

    def _objective(self, cp: Any, x: Any, problem: ConeProblem) -> Any:
        """0.5 x'Px + q'x as a cvxpy expression (diagonal P as a sum of squares for ECOS)."""
        linear = np.asarray(problem.q, dtype=np.float64) @ x
        P = problem.P
        if P is None or P.nnz == 0 or not np.any(P.data):
            return linear
        if self.solver not in _NATIVE_QUADRATIC and _is_diagonal(P):
            # Avoids cvxpy's dense factorization of P for solvers without quadratic objectives.
            d = P.diagonal()
            keep = np.flatnonzero(d)
            if np.any(d[keep] < 0):
                raise ValueError("P has a negative diagonal entry; the objective is not convex")
            return 0.5 * cp.sum_squares(cp.multiply(np.sqrt(d[keep]), x[keep])) + linear
        return 0.5 * cp.quad_form(x, symmetric_from_upper(P), assume_PSD=True) + linear

    def _constraints(self, cp: Any, x: Any, problem: ConeProblem) -> list[Any]:
        """Rows of A x + s = b with s in K, written as cvxpy constraints on s = b - A x."""
        A, b, spec = problem.A.tocsr(), np.asarray(problem.b, dtype=np.float64), problem.cones
        constraints: list[Any] = []
        nz, nn = spec.n_zero, spec.n_nonneg
        if nz:
            constraints.append(A[:nz] @ x == b[:nz])
        if nn:
            constraints.append(A[nz : nz + nn] @ x <= b[nz : nz + nn])
        starts = spec.soc_starts()
        dims = np.asarray(spec.soc_dims, dtype=np.int64)
        for d in np.unique(dims):
            first = starts[dims == d]  # one column per cone of this dimension
            t = b[first] - A[first] @ x
            tail_rows = (first[None, :] + np.arange(1, d)[:, None]).ravel(order="F")
            tail = cp.reshape(b[tail_rows] - A[tail_rows] @ x, (int(d) - 1, first.size), order="F")
            constraints.append(cp.SOC(t, tail, axis=0))
        return constraints

    @staticmethod
    def _multipliers(model: Any, problem: ConeProblem) -> np.ndarray | None:
        """Row multipliers in Clarabel's sign from cvxpy's duals of ``A x == b`` and ``A x <= b``
        (cvxpy's Lagrangian adds y'(A x - b) for both); None with second-order cones, whose
        duals cvxpy reports in a different layout."""
        spec = problem.cones
        if spec.soc_dims or not model.constraints:
            return None
        parts = [
            np.atleast_1d(np.asarray(c.dual_value, dtype=np.float64)) for c in model.constraints
        ]
        y = np.concatenate(parts) if parts else np.zeros(0)
        return y if y.size == problem.m and np.all(np.isfinite(y)) else None

    def solve(self, problem: ConeProblem, *, time_limit_s: float | None = None) -> ConicSolution:
        """Build the cvxpy model, solve it, and map cvxpy's status to a ConicStatus."""
        start = perf_counter()
        problem.validate()
        import cvxpy as cp

        x = cp.Variable(problem.n)
        model = cp.Problem(
            cp.Minimize(self._objective(cp, x, problem)), self._constraints(cp, x, problem)
        )
        options = {**self.solver_options, **self._time_limit_options(time_limit_s)}
        stats: Any = None
        try:
            with warnings.catch_warnings():
                # The mapped status already says "inaccurate"; cvxpy's warning would only repeat it.
                warnings.filterwarnings("ignore", message="Solution may be inaccurate")
                model.solve(solver=self.solver, **options)  # type: ignore[no-untyped-call]  # cvxpy leaves solve untyped
            raw_status = str(model.status)
            stats = model.solver_stats
        except cp.error.SolverError as exc:
            raw_status = f"solver_error: {exc}"
        wall = perf_counter() - start
        status = map_cvxpy_status(raw_status if stats is not None else "solver_error")
        if status is ConicStatus.TIME_LIMIT and time_limit_s is None:
            status = ConicStatus.NUMERICAL_ERROR  # user_limit without a time limit: iteration cap
        if status.usable and x.value is None:
            status = ConicStatus.NUMERICAL_ERROR  # a "solved" status without a point is unusable
        solve_time = getattr(stats, "solve_time", None)
        solve_time_s = float(solve_time) if solve_time is not None else wall
        iterations = getattr(stats, "num_iters", None)
        return ConicSolution(
            x=np.asarray(x.value, dtype=np.float64) if status.usable else None,
            status=status,
            raw_status=raw_status,
            objective=float(model.value) if status.usable else None,
            solve_time_s=solve_time_s,
            iterations=int(iterations) if iterations is not None else 0,
            setup_time_s=max(wall - solve_time_s, 0.0),
            solver=self.name,
            y=self._multipliers(model, problem) if status.usable else None,
        )
