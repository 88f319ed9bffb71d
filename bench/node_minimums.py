"""The fewest nodes each method can use, tried on its built-in problems: each run's status,
failure code, iterations and the points the method actually used, at and just below the
minimum the contract enforces (counts below it are set past validation, to show why).

    python -m bench.node_minimums [--max-iterations 10]

The runs are capped at ``--max-iterations`` SCP iterations: the question is whether a method
starts and iterates with so few nodes, not whether it converges (docs/problem-contract.md,
"Method").
"""

from __future__ import annotations

import argparse
import time
from typing import Any

from app.schemas import ProblemDocument
from app.submission import apply_overrides
from worker.solver.api import solve_problem
from worker.solver.scenarios import get_scenario

RUNS: tuple[tuple[str, dict[str, Any], dict[str, Any]], ...] = (
    *(
        (scenario, {"name": "foh-ptr"}, {"nodes": n})
        for scenario in (
            "rlv-max-terminal-velocity",
            "rlv-max-terminal-velocity-nfz",
            "rlv-max-terminal-velocity-active-nfz",
        )
        for n in (3, 6, 8, 9)
    ),
    ("rlv-min-heat-load", {"name": "energy-scp"}, {"nodes": 2}),
    ("rlv-min-heat-load", {"name": "energy-scp"}, {"nodes": 3}),
    ("rlv-min-time-hp", {"name": "hp-scp", "nodes": 3, "intervals": 1}, {"nodes": 2}),
    ("rlv-min-time-hp", {"name": "hp-scp", "nodes": 3, "intervals": 1}, {}),
    ("cav-h-min-time", {"name": "cheb-scvx", "nodes": 41}, {"nodes": 5}),
    ("cav-h-min-time", {"name": "cheb-scvx", "nodes": 3, "intervals": 1}, {}),
    (
        "shuttle-skip-min-propellant",
        {"name": "lgl-sqp", "nodes": 3, "degree": 2, "initial_guess": "constant"},
        {},
    ),
)
"""(scenario, method patch, options set past validation) of every run."""


def run(scenario: str, method: dict[str, Any], forced: dict[str, Any], cap: int) -> str:
    """One row: the run's setup and how it ended."""
    patch = {"method": {**method, "max_iterations": cap}}
    problem = ProblemDocument.model_validate(apply_overrides(get_scenario(scenario).problem, patch))
    problem.method = problem.method.model_copy(update=forced)  # below the minimum: unvalidated
    start = time.perf_counter()
    result = solve_problem(problem)
    failure = result.get("failure") or {}
    used = (result.get("trajectory") or {}).get("nodes", "-")
    options = {k: v for k, v in problem.method.model_dump().items() if k in ("nodes", "intervals")}
    return (
        f"| {scenario} | {method['name']} {options} | {result['status']} | "
        f"{failure.get('code') or '-'} | {result['timing']['iterations']} | {used} | "
        f"{time.perf_counter() - start:.1f} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-iterations", type=int, default=10)
    args = parser.parse_args()
    print("| problem | method, nodes | status | failure | iterations | points used | s |")
    print("|---|---|---|---|---|---|---|")
    for scenario, method, forced in RUNS:
        print(run(scenario, method, forced, args.max_iterations), flush=True)


if __name__ == "__main__":
    main()
