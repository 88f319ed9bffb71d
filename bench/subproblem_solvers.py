"""Whole solves of built-in scenarios with each subproblem solver, side by side.

    python -m bench.subproblem_solvers --scenarios rlv-max-terminal-velocity --repeats 5

Each scenario is solved with each backend of ``--backends`` in turn, ``--repeats`` rounds that
alternate the backends (a busy machine slows both alike), and the table gives per backend the
median CPU time of the whole solve (``solve_problem``: optimization and verification), the
conic solvers' own time summed over the history, the status, the iterations, the objective and
which solver answered each subproblem; the last column is the median CPU time against the first
backend's.
"""

from __future__ import annotations

import argparse
import copy
import statistics
import time
from typing import Any

from app.schemas import ProblemDocument
from worker.solver.api import solve_problem
from worker.solver.scenarios import get_scenario


def parser() -> argparse.ArgumentParser:
    """main()'s argument parser, apart so a test checks the documented commands against it."""
    cli = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cli.add_argument("--scenarios", nargs="+", default=["rlv-max-terminal-velocity"])
    cli.add_argument("--backends", nargs="+", default=["clarabel", "piqp"])
    cli.add_argument("--repeats", type=int, default=5)
    return cli


def solve(scenario: str, backend: str) -> tuple[float, dict[str, Any]]:
    """CPU seconds of one whole solve of ``scenario`` with ``backend``, and its result."""
    document = copy.deepcopy(get_scenario(scenario).problem)
    document["method"] = {**document.get("method", {}), "conic_backend": backend}
    problem = ProblemDocument.model_validate(document)
    start = time.process_time()
    result = solve_problem(problem)
    return time.process_time() - start, result


def row(scenario: str, backend: str, cpu: list[float], first: float, result: dict[str, Any]) -> str:
    """One table row: the median of ``cpu`` and what the last result says."""
    history = result.get("history") or []
    conic = sum(float(r.get("conic_solve_s") or 0.0) for r in history)
    solvers = sorted({str(r.get("conic_solver")) for r in history})
    objective = (result.get("objective") or {}).get("value")
    median = statistics.median(cpu)
    value = "-" if objective is None else f"{objective:.9g}"
    return (
        f"| {scenario} | {backend} | {median:.3f} | {conic:.3f} | {result['status']} | "
        f"{len(history)} | {value} | {', '.join(solvers)} | {median / first:.2f} |"
    )


def main() -> None:
    args = parser().parse_args()
    print(
        "| scenario | backend | median CPU s | conic s | status | iterations | objective | "
        "solvers | CPU / first |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for scenario in args.scenarios:
        cpu: dict[str, list[float]] = {b: [] for b in args.backends}
        last: dict[str, dict[str, Any]] = {}
        for _ in range(args.repeats):
            for backend in args.backends:
                seconds, last[backend] = solve(scenario, backend)
                cpu[backend].append(seconds)
        first = statistics.median(cpu[args.backends[0]])
        for backend in args.backends:
            print(row(scenario, backend, cpu[backend], first, last[backend]), flush=True)


if __name__ == "__main__":
    main()
