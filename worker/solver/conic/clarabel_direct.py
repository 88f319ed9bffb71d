"""Direct Clarabel backend that keeps its solver between calls and only updates data when it can.

Successive SCP subproblems share one sparsity pattern, so Clarabel's symbolic KKT analysis is done
once and later iterations pay for numeric work only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from time import perf_counter
from typing import Any

import clarabel
import numpy as np
import scipy.sparse as sp

from worker.solver.conic.base import ConicSolution
from worker.solver.conic.problem import ConeProblem, ConeSpec, same_pattern
from worker.solver.conic.status import ConicStatus, clarabel_status_name, map_clarabel_status


def clarabel_cones(spec: ConeSpec) -> list[Any]:
    """Translate a ConeSpec into Clarabel's list of cone objects, in row order."""
    cones: list[Any] = []
    if spec.n_zero:
        cones.append(clarabel.ZeroConeT(spec.n_zero))
    if spec.n_nonneg:
        cones.append(clarabel.NonnegativeConeT(spec.n_nonneg))
    cones.extend(clarabel.SecondOrderConeT(d) for d in spec.soc_dims)
    return cones


@dataclass
class _Structure:
    """What must match for a cached Clarabel solver to accept a data-only update."""

    n: int
    m: int
    cones: ConeSpec
    P: sp.csc_matrix | None
    A: sp.csc_matrix

    def matches(self, problem: ConeProblem) -> bool:
        """True when ``problem`` has the same dimensions, cones and sparsity patterns."""
        return (
            _is_csc(problem.A)
            and (problem.P is None or _is_csc(problem.P))
            and self.n == problem.n
            and self.m == problem.m
            and self.cones == problem.cones
            and same_pattern(self.P, problem.P)
            and same_pattern(self.A, problem.A)
        )


def _is_csc(matrix: Any) -> bool:
    """True for a scipy.sparse matrix in CSC format."""
    return bool(sp.issparse(matrix) and matrix.format == "csc")


def _values(array: Any) -> memoryview:
    """A float64 vector as a flat buffer for ``update``, which reads it as a sequence.

    clarabel's bindings take any sequence of floats; a memoryview hands over the same float64
    values several times faster than a NumPy array (whose items are NumPy scalars) or a list.
    """
    return np.ascontiguousarray(array, dtype=np.float64).data


def _pattern_copy(matrix: sp.csc_matrix | None) -> sp.csc_matrix | None:
    """Keep only the pattern of ``matrix`` (own copies of indptr/indices, no data)."""
    if matrix is None:
        return None
    return sp.csc_matrix(
        (np.zeros(matrix.nnz), matrix.indices.copy(), matrix.indptr.copy()), shape=matrix.shape
    )


ROBUST_STATIC_REGULARIZATION = 1e-7
"""Clarabel's static regularization (default 1e-8) on the last try after a numerical error: a
foh-ptr subproblem with soft-terminal weights of 3e6 beside unit ones stalled at a relative gap
of 5e-2 on a fresh solver at the default and solved in 20 iterations with this."""


ROBUST_RETRY_ON = ("NumericalError", "InsufficientProgress")
"""Clarabel's statuses that get the last try (not its iteration or time limit)."""


class ClarabelBackend:
    """Solves ConeProblems with the ``clarabel`` package, reusing the solver on repeated patterns.

    ``setups`` counts fresh solver constructions, ``updates`` counts data-only reuses. A reused
    solver keeps the equilibration scaling of the problem it was built for, which pays off when
    successive problems differ little (SCP iterations); pass ``reuse=False`` otherwise.
    """

    name = "clarabel"

    def __init__(
        self,
        *,
        tol_gap_abs: float = 1e-8,
        tol_gap_rel: float = 1e-8,
        tol_feas: float = 1e-8,
        max_iter: int = 200,
        reuse: bool = True,
    ) -> None:
        """Store solver tolerances (Clarabel's defaults) and whether to reuse the solver."""
        self.tol_gap_abs = tol_gap_abs
        self.tol_gap_rel = tol_gap_rel
        self.tol_feas = tol_feas
        self.max_iter = max_iter
        self.reuse = reuse
        self.setups = 0
        self.updates = 0
        self._solver: Any = None
        self._structure: _Structure | None = None
        self._time_limit = math.inf
        self._last_P: Any = None
        self._robust = False  # the settings of the last resort (``_again``)
        self._inside_s = 0.0  # time inside Clarabel's constructor or update() for the last solve

    def reset(self) -> None:
        """Drop the cached solver so the next solve starts from scratch."""
        self._solver = None
        self._structure = None
        self._last_P = None

    def _settings(self, time_limit: float) -> Any:
        """Clarabel settings for one solve: quiet, our tolerances, the given time limit."""
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.tol_gap_abs = self.tol_gap_abs
        settings.tol_gap_rel = self.tol_gap_rel
        settings.tol_feas = self.tol_feas
        settings.max_iter = self.max_iter
        settings.time_limit = time_limit
        settings.input_sparse_dropzeros = False  # explicit zeros must stay for data updates
        if self._robust:
            settings.static_regularization_constant = ROBUST_STATIC_REGULARIZATION
        return settings

    def _prepare(self, problem: ConeProblem, time_limit: float) -> None:
        """Update the cached solver in place when the structure matches, else build a new one.

        A problem on the cached pattern was fully validated when that pattern was first seen,
        so only its values are checked here.
        """
        if self.reuse and self._structure is not None and self._structure.matches(problem):
            problem.validate_values()
            data: dict[str, Any] = {
                "q": _values(problem.q),
                "b": _values(problem.b),
                "A": _values(problem.A.data),
            }
            if problem.P is not None and problem.P is not self._last_P:
                data["P"] = _values(problem.P.data)  # an unchanged P object is not sent again
            if time_limit != self._time_limit:
                data["settings"] = self._settings(time_limit)
            t0 = perf_counter()
            self._solver.update(**data)
            self._inside_s = perf_counter() - t0
            self._last_P = problem.P
            self._time_limit = time_limit
            self.updates += 1
            return
        problem.validate()
        q = np.ascontiguousarray(problem.q, dtype=np.float64)
        b = np.ascontiguousarray(problem.b, dtype=np.float64)
        n = problem.n
        P = problem.P if problem.P is not None else sp.csc_matrix((n, n))
        settings = self._settings(time_limit)
        cones = clarabel_cones(problem.cones)
        t0 = perf_counter()
        self._solver = clarabel.DefaultSolver(P, q, problem.A, b, cones, settings)
        self._inside_s = perf_counter() - t0
        self._time_limit = time_limit
        self._last_P = problem.P
        self.setups += 1
        self._structure = None
        if self.reuse and self._solver.is_data_update_allowed():
            P_pattern, A_pattern = _pattern_copy(problem.P), _pattern_copy(problem.A)
            self._structure = _Structure(n, problem.m, problem.cones, P_pattern, A_pattern)

    def solve(self, problem: ConeProblem, *, time_limit_s: float | None = None) -> ConicSolution:
        """Solve ``problem``; ``time_limit_s`` bounds Clarabel's solve time (None: no limit).

        A reused solver that reports numerical trouble (InsufficientProgress, NumericalError,
        MaxIterations) is rebuilt once and the problem solved again: its equilibration was
        computed for an earlier iterate, and a fresh one often cures the stall (measured on
        paper 002 case 1 with an active zone at 120 nodes: InsufficientProgress after 37
        interior-point iterations on the reused solver, Solved in 37 from scratch). A fresh solver
        that still fails gets one last try with ``ROBUST_STATIC_REGULARIZATION``. The times of
        all attempts are reported together.
        """
        updates = self.updates
        result = self._solve_once(problem, time_limit_s)
        if result.status == ConicStatus.NUMERICAL_ERROR and self.updates != updates:
            result = self._again(problem, time_limit_s, result, robust=False)
        if result.raw_status in ROBUST_RETRY_ON:
            result = self._again(problem, time_limit_s, result, robust=True)
        return result

    def _again(
        self,
        problem: ConeProblem,
        time_limit_s: float | None,
        before: ConicSolution,
        *,
        robust: bool,
    ) -> ConicSolution:
        """``problem`` solved again from scratch after ``before`` failed, its times added; with
        ``robust`` on a solver with ``ROBUST_STATIC_REGULARIZATION`` (not cached)."""
        spent = before.solve_time_s + before.setup_time_s
        remaining = None if time_limit_s is None else time_limit_s - spent
        if remaining is not None and remaining <= 0.0:
            return before
        self.reset()
        self._robust = robust
        try:
            after = self._solve_once(problem, remaining)
        finally:
            if robust:
                self.reset()  # the next problem gets the default settings again
            self._robust = False
        return replace(
            after,
            solve_time_s=before.solve_time_s + after.solve_time_s,
            setup_time_s=before.setup_time_s + after.setup_time_s,
            clarabel_setup_s=before.clarabel_setup_s + after.clarabel_setup_s,
            iterations=before.iterations + after.iterations,
        )

    def _solve_once(self, problem: ConeProblem, time_limit_s: float | None) -> ConicSolution:
        """One Clarabel solve of ``problem`` on the cached solver (updated) or a new one."""
        start = perf_counter()
        self._prepare(problem, math.inf if time_limit_s is None else float(time_limit_s))
        solve_start = perf_counter()
        result = self._solver.solve()
        # Timed here rather than read from ``result.solve_time``: in clarabel 0.11 that figure also
        # holds the constructor's setup timer, so after a data update it would count setup again.
        solve_time = perf_counter() - solve_start
        status = map_clarabel_status(result.status)
        x = np.asarray(result.x, dtype=np.float64) if status.usable else None
        objective = float(result.obj_val) if status.usable else None
        wall = perf_counter() - start
        return ConicSolution(
            x=x,
            status=status,
            raw_status=clarabel_status_name(result.status),
            objective=objective,
            solve_time_s=solve_time,
            iterations=int(result.iterations),
            setup_time_s=max(wall - solve_time, 0.0),
            clarabel_setup_s=self._inside_s,
            solver=self.name,
            y=np.asarray(result.z, dtype=np.float64) if status.usable else None,
        )
