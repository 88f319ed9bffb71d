"""PIQP backend for the subproblems that are quadratic programs, Clarabel kept as the fallback.

PIQP (Schwan, Jiang, Kuhn & Jones, "PIQP: A Proximal Interior-Point Quadratic Programming
Solver", IEEE CDC 2023) solves min 0.5 x'Px + c'x s.t. A x = b, h_l <= G x <= h_u. A
``ConeProblem`` with no second-order cones maps onto it directly: its zero rows are A x = b, its
nonnegative rows (A x + s = b, s >= 0) are G x <= h. The solver is kept between calls and updated
in place while the sparsity pattern stays. Anything PIQP does not solve to its tolerance, and any
problem with second-order cones, is solved by Clarabel (``clarabel_direct``), and the solution
says so (``solver``). PIQP has no time limit of its own: the SCP driver's applies between solves.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from time import perf_counter
from typing import Any

import numpy as np
import piqp
import scipy.sparse as sp

from worker.solver.conic.base import ConicSolution
from worker.solver.conic.clarabel_direct import ClarabelBackend
from worker.solver.conic.problem import ConeProblem, same_pattern
from worker.solver.conic.status import ConicStatus


@dataclass
class _Parts:
    """A QP in PIQP's form: P (upper triangle), c, the equality rows and the inequality rows."""

    P: sp.csc_matrix
    c: np.ndarray
    A: sp.csc_matrix
    b: np.ndarray
    G: sp.csc_matrix
    h_u: np.ndarray

    @classmethod
    def of(cls, problem: ConeProblem) -> _Parts:
        """The zero rows of ``problem`` as equalities, its nonnegative rows as G x <= h."""
        nz = problem.cones.n_zero
        rows = problem.A.tocsr()
        n = problem.n
        P = problem.P if problem.P is not None else sp.csc_matrix((n, n))
        b = np.ascontiguousarray(problem.b, dtype=np.float64)
        return cls(
            P=sp.csc_matrix(P),
            c=np.ascontiguousarray(problem.q, dtype=np.float64),
            A=rows[:nz].tocsc(),
            b=b[:nz],
            G=rows[nz:].tocsc(),
            h_u=b[nz:],
        )

    def same_pattern(self, other: _Parts) -> bool:
        """Whether ``other`` can update a solver set up with this one (same shapes, patterns)."""
        return all(
            same_pattern(mine, theirs)
            for mine, theirs in ((self.P, other.P), (self.A, other.A), (self.G, other.G))
        )


class PiqpBackend:
    """Solves QP-shaped ConePrograms with PIQP (reused on repeated patterns), the rest and every
    failure with Clarabel. ``setups``/``updates`` count PIQP's fresh setups and data updates,
    ``fallbacks`` the problems Clarabel answered."""

    name = "piqp"

    def __init__(self, *, eps_abs: float = 1e-8, eps_rel: float = 1e-9, max_iter: int = 200):
        """PIQP's tolerances (its defaults) and iteration limit (Clarabel's)."""
        self.eps_abs, self.eps_rel, self.max_iter = eps_abs, eps_rel, max_iter
        self.clarabel = ClarabelBackend()
        self.setups = 0
        self.updates = 0
        self.fallbacks = 0
        self._solver: Any = None
        self._parts: _Parts | None = None

    def reset(self) -> None:
        """Drop the cached solvers so the next solve starts from scratch."""
        self._solver = None
        self._parts = None
        self.clarabel.reset()

    def solve(self, problem: ConeProblem, *, time_limit_s: float | None = None) -> ConicSolution:
        """Solve ``problem`` with PIQP when it has no second-order cones; Clarabel otherwise, and
        again when PIQP does not report it solved (the times of both attempts added)."""
        if problem.cones.soc_dims:
            return self.clarabel.solve(problem, time_limit_s=time_limit_s)
        first = self._solve_piqp(problem)
        if first.status == ConicStatus.OPTIMAL:
            return first
        self.fallbacks += 1
        remaining = None
        if time_limit_s is not None:
            remaining = time_limit_s - first.solve_time_s - first.setup_time_s
            if remaining <= 0.0:
                return first
        second = self.clarabel.solve(problem, time_limit_s=remaining)
        return replace(
            second,
            solve_time_s=first.solve_time_s + second.solve_time_s,
            setup_time_s=first.setup_time_s + second.setup_time_s,
            iterations=first.iterations + second.iterations,
            solver=f"{self.name}>{second.solver}",
        )

    def _prepare(self, parts: _Parts, problem: ConeProblem) -> None:
        """Update the cached solver when the pattern matches, else set up a new one."""
        inf = np.full(parts.h_u.size, -np.inf)
        if self._parts is not None and self._parts.same_pattern(parts):
            problem.validate_values()
            self._solver.update(parts.P, parts.c, parts.A, parts.b, parts.G, inf, parts.h_u)
            self.updates += 1
        else:
            problem.validate()
            solver = piqp.SparseSolver()
            settings = solver.settings
            settings.verbose = False
            settings.eps_abs, settings.eps_rel = self.eps_abs, self.eps_rel
            settings.max_iter = self.max_iter
            solver.setup(parts.P, parts.c, parts.A, parts.b, parts.G, inf, parts.h_u)
            self._solver = solver
            self.setups += 1
        self._parts = parts

    def _solve_piqp(self, problem: ConeProblem) -> ConicSolution:
        """One PIQP solve; its multipliers in Clarabel's sign (P x + q + A'y = 0)."""
        start = perf_counter()
        self._prepare(_Parts.of(problem), problem)
        solve_start = perf_counter()
        status = self._solver.solve()
        solve_time = perf_counter() - solve_start
        result = self._solver.result
        raw = str(status).rsplit(".", 1)[-1]
        mapped = _STATUS.get(raw, ConicStatus.NUMERICAL_ERROR)
        usable = mapped == ConicStatus.OPTIMAL
        x = np.array(result.x, dtype=np.float64) if usable else None
        y = None
        if usable:
            z = np.asarray(result.z_u, dtype=np.float64) - np.asarray(result.z_l, np.float64)
            y = np.concatenate([np.asarray(result.y, dtype=np.float64), z])
        return ConicSolution(
            x=x,
            status=mapped,
            raw_status=raw,
            objective=float(result.info.primal_obj) if usable else None,
            solve_time_s=solve_time,
            iterations=int(result.info.iter),
            setup_time_s=max(perf_counter() - start - solve_time, 0.0),
            solver=self.name,
            y=y,
        )


_STATUS: dict[str, ConicStatus] = {
    "PIQP_SOLVED": ConicStatus.OPTIMAL,
    "PIQP_PRIMAL_INFEASIBLE": ConicStatus.INFEASIBLE,
    "PIQP_DUAL_INFEASIBLE": ConicStatus.INFEASIBLE,
    "PIQP_MAX_ITER_REACHED": ConicStatus.NUMERICAL_ERROR,
    "PIQP_NUMERICS": ConicStatus.NUMERICAL_ERROR,
    "PIQP_UNSOLVED": ConicStatus.NUMERICAL_ERROR,
    "PIQP_INVALID_SETTINGS": ConicStatus.NUMERICAL_ERROR,
}
"""PIQP's statuses as the SCP loop sees them; every one but solved goes on to Clarabel."""
