"""Benchmark of the conic layer on an SOCP shaped like one SCP subproblem.

Measures SparseAssembler assembly, a fresh Clarabel setup+solve, a data-update re-solve and,
optionally, cvxpy. Run: ``python -m bench.conic_backends [--nodes 120] [--repeats 5]
[--perturb 0.05] [--cvxpy]``.
"""

from __future__ import annotations

import argparse
import statistics
from collections.abc import Callable
from dataclasses import dataclass
from time import perf_counter

import numpy as np
from numpy.typing import NDArray

from worker.solver.conic import (
    ClarabelBackend,
    ConeProblem,
    ConeSpec,
    ConicSolution,
    CvxpyBackend,
    SparseAssembler,
)

N_STATE = 6
N_CONTROL = 3
# per node: states, controls, virtual controls, their L1 bounds, trust-region radius
N_PER_NODE = N_STATE + N_CONTROL + 2 * N_STATE + 1


@dataclass
class Layout:
    """Fixed triplet structure of the SCP-like SOCP, plus the feasible point used for b."""

    nodes: int
    A: SparseAssembler
    A_rows: NDArray[np.int64]
    A_cols: NDArray[np.int64]
    P: SparseAssembler
    cones: ConeSpec


def _var(node: int, offset: int) -> int:
    """Column of variable ``offset`` at ``node``."""
    return node * N_PER_NODE + offset


def build_layout(nodes: int) -> Layout:
    """Triplet pattern: dynamics equalities, control boxes, |nu| <= eta, two SOC families."""
    rows: list[int] = []
    cols: list[int] = []
    row = 0
    xs, us, nus = 0, N_STATE, N_STATE + N_CONTROL
    etas, rs = nus + N_STATE, N_PER_NODE - 1
    for k in range(nodes - 1):  # x_{k+1} - A x_k - B u_k - nu_k = c
        for i in range(N_STATE):
            targets = [_var(k + 1, xs + i), _var(k, nus + i)]
            targets += [_var(k, xs + j) for j in range(N_STATE)]
            targets += [_var(k, us + j) for j in range(N_CONTROL)]
            rows += [row] * len(targets)
            cols += targets
            row += 1
    n_zero = row
    for k in range(nodes):  # control boxes: +-u <= bound
        for j in range(N_CONTROL):
            for _ in range(2):
                rows.append(row)
                cols.append(_var(k, us + j))
                row += 1
    for k in range(nodes):  # +-nu - eta <= 0
        for i in range(N_STATE):
            for _ in range(2):
                rows += [row, row]
                cols += [_var(k, nus + i), _var(k, etas + i)]
                row += 1
    n_nonneg = row - n_zero
    dims: list[int] = []
    for k in range(nodes):  # ||(u_1, u_2)|| <= u_0   (dimension 3)
        for j in range(N_CONTROL):
            rows.append(row + j)
            cols.append(_var(k, us + j))
        row += 3
        dims.append(3)
    for k in range(nodes):  # ||x_k - xbar_k|| <= r_k   (dimension 7)
        rows.append(row)
        cols.append(_var(k, rs))
        for i in range(N_STATE):
            rows.append(row + 1 + i)
            cols.append(_var(k, xs + i))
        row += 1 + N_STATE
        dims.append(1 + N_STATE)
    n = nodes * N_PER_NODE
    A_rows, A_cols = np.asarray(rows), np.asarray(cols)
    diag = np.arange(n)
    return Layout(
        nodes=nodes,
        A=SparseAssembler(A_rows, A_cols, (row, n)),
        A_rows=A_rows,
        A_cols=A_cols,
        P=SparseAssembler(diag, diag, (n, n), upper_triangular=True),
        cones=ConeSpec(n_zero, n_nonneg, tuple(dims)),
    )


@dataclass
class InteriorPoint:
    """A point x0 and slack s strictly inside K; b = A x0 + s makes any A strictly feasible."""

    x0: NDArray[np.float64]
    s: NDArray[np.float64]


def interior_point(layout: Layout, rng: np.random.Generator) -> InteriorPoint:
    """Random x0 and a slack with positive nonnegative rows and SOC heads above their tails."""
    spec = layout.cones
    s = np.zeros(spec.n_rows)
    s[spec.n_zero : spec.n_zero + spec.n_nonneg] = rng.uniform(0.1, 1.0, spec.n_nonneg)
    for start, d in zip(spec.soc_starts(), spec.soc_dims, strict=True):
        tail = rng.standard_normal(d - 1)
        s[start] = np.linalg.norm(tail) + rng.uniform(0.1, 1.0)
        s[start + 1 : start + d] = tail
    return InteriorPoint(x0=rng.standard_normal(layout.A.shape[1]), s=s)


def random_problem(layout: Layout, point: InteriorPoint, rng: np.random.Generator) -> ConeProblem:
    """Strictly feasible, bounded instance (P positive definite) with random values."""
    A = layout.A.assemble(rng.standard_normal(layout.A.n_triplets))
    P = layout.P.assemble(rng.uniform(0.01, 1.0, layout.P.n_triplets))
    q = rng.standard_normal(A.shape[1])
    return ConeProblem(P=P, q=q, A=A, b=A @ point.x0 + point.s, cones=layout.cones)


def perturbed(
    problem: ConeProblem, point: InteriorPoint, rel: float, rng: np.random.Generator
) -> ConeProblem:
    """Same pattern, A, P, q scaled by (1 + rel * noise): stand-in for the next SCP iterate."""
    A = problem.A.copy()
    A.data = A.data * (1.0 + rel * rng.standard_normal(A.nnz))
    P = None
    if problem.P is not None:
        P = problem.P.copy()
        P.data = P.data * (1.0 + rel * rng.uniform(0.0, 1.0, P.nnz))
    q = problem.q * (1.0 + rel * rng.standard_normal(problem.n))
    return ConeProblem(P=P, q=q, A=A, b=A @ point.x0 + point.s, cones=problem.cones)


def _median_time(fn: Callable[[], object], repeats: int) -> float:
    """Median wall time of ``fn`` over ``repeats`` calls."""
    times = []
    for _ in range(repeats):
        start = perf_counter()
        fn()
        times.append(perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    """Print assembly, fresh-solve and update-solve timings for the SCP-like SOCP."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--nodes", type=int, default=120)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument(
        "--perturb",
        type=float,
        default=0.05,
        help="relative change between successive problems (0: independent random values)",
    )
    parser.add_argument("--cvxpy", action="store_true", help="also time cvxpy:CLARABEL once")
    args = parser.parse_args()
    rng = np.random.default_rng(1)

    start = perf_counter()
    layout = build_layout(args.nodes)
    structure_s = perf_counter() - start
    point = interior_point(layout, rng)
    first = random_problem(layout, point, rng)
    problems = [first] + [
        perturbed(first, point, args.perturb, rng)
        if args.perturb > 0
        else random_problem(layout, point, rng)
        for _ in range(args.repeats)
    ]
    values = rng.standard_normal(layout.A.n_triplets)
    assemble_s = _median_time(lambda: layout.A.assemble(values), max(args.repeats, 20))
    print(
        f"n={first.n} m={first.m} zero={first.cones.n_zero} nonneg={first.cones.n_nonneg} "
        f"soc={len(first.cones.soc_dims)} nnz(A)={first.A.nnz}"
    )
    print(f"SparseAssembler structure (once): {structure_s * 1e3:8.2f} ms (incl. triplet lists)")
    print(f"SparseAssembler.assemble(A):      {assemble_s * 1e3:8.3f} ms")

    fresh: list[ConicSolution] = []
    fresh_wall: list[float] = []
    updated: list[ConicSolution] = []
    update_wall: list[float] = []
    backend = ClarabelBackend()
    backend.solve(first)
    for problem in problems[1:]:  # interleaved so machine load affects both alike
        start = perf_counter()
        fresh.append(ClarabelBackend(reuse=False).solve(problem))
        fresh_wall.append(perf_counter() - start)
        start = perf_counter()
        updated.append(backend.solve(problem))
        update_wall.append(perf_counter() - start)
    for label, sols, walls in (("fresh ", fresh, fresh_wall), ("update", updated, update_wall)):
        print(
            f"clarabel {label}: wall {statistics.median(walls) * 1e3:8.2f} ms, "
            f"setup {statistics.median(s.setup_time_s for s in sols) * 1e3:8.2f} ms, "
            f"solve {statistics.median(s.solve_time_s for s in sols) * 1e3:8.2f} ms, "
            f"iters {statistics.median(s.iterations for s in sols):.0f}, "
            f"status {sorted({str(s.status) for s in sols})}"
        )
    gaps = [
        abs((a.objective or 0.0) - (b.objective or 0.0)) / max(1.0, abs(a.objective or 0.0))
        for a, b in zip(fresh, updated, strict=True)
    ]
    print(f"max relative objective gap fresh vs update: {max(gaps):.2e} (setups={backend.setups})")
    if args.cvxpy:
        start = perf_counter()
        sol = CvxpyBackend("CLARABEL").solve(problems[1])
        print(
            f"cvxpy:CLARABEL: wall {(perf_counter() - start) * 1e3:8.2f} ms, "
            f"solve {sol.solve_time_s * 1e3:8.2f} ms, objective gap "
            f"{abs((sol.objective or 0.0) - (fresh[0].objective or 0.0)):.2e}"
        )


if __name__ == "__main__":
    main()
