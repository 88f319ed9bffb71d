"""The verification's cost against the optimization's, on every built-in scenario.

Per scenario at its default options, medians over repeated solves in one process (after a
warm-up): the optimization's wall time (the SCP loop), the verification's wall time with the
compiled right-hand side and restarts at the nodes (the default), the verification with the
Python right-hand side (the form used for models without a compiled form, also restarted), and
the ratios verification / optimization. The aim is a verification at most 0.25 x the
optimization. Ratios within one run are robust to a shared, noisy machine. Scenarios of a method
that flies phases (lgl-sqp: minutes per solve) are left out; their verification time is in
``bench.skip_table3``'s rows.

    python -m bench.verification [--repeats 5] [--only NAME ...] [--nodes N ...]
"""

from __future__ import annotations

import argparse
import statistics
import time
from typing import Any
from unittest import mock

from app.schemas import ProblemDocument
from worker.solver import verification
from worker.solver.methods import METHODS
from worker.solver.problem import build_problem
from worker.solver.scenarios import get_scenario, list_scenarios
from worker.solver.trajectory import OptimizedTrajectory
from worker.solver.verification import verify
from worker.solver.warmup import warm_up


def bench(name: str, repeats: int, nodes: int | None = None) -> dict[str, Any]:
    """Median optimization and verification times of scenario ``name`` (at ``nodes`` nodes when
    given, else its default)."""
    raw = dict(get_scenario(name).problem)
    if nodes is not None:
        raw["method"] = {**raw["method"], "nodes": nodes}
    doc = ProblemDocument.model_validate(raw)
    model = build_problem(doc)
    method = METHODS[doc.method.name]
    outcome = method.run(model, doc.method, None, None)  # warm-up: imports, caches
    optimization = []
    for _ in range(repeats):
        start = time.perf_counter()
        outcome = method.run(model, doc.method, None, None)
        optimization.append(time.perf_counter() - start)
    traj = outcome.trajectory
    assert isinstance(traj, OptimizedTrajectory)
    verify(model, traj)
    compiled, python = [], []
    report: dict[str, Any] = {}
    for _ in range(repeats):
        start = time.perf_counter()
        report = verify(model, traj)
        compiled.append(time.perf_counter() - start)
    with mock.patch.object(verification, "compiled_parameters", lambda forces, omega: None):
        for _ in range(max(1, repeats // 2)):
            start = time.perf_counter()
            verify(model, traj)
            python.append(time.perf_counter() - start)
    opt = statistics.median(optimization)
    ver = statistics.median(compiled)
    ver_py = statistics.median(python)
    return {
        "scenario": name,
        "method": doc.method.name,
        "nodes": doc.method.nodes,
        "optimization_s": opt,
        "verification_s": ver,
        "ratio": ver / opt,
        "python_rhs_s": ver_py,
        "python_ratio": ver_py / opt,
        "steps": report["integrator"]["steps"],
        "feasible": report["feasible"],
    }


def _phased(name: str) -> bool:
    """Whether scenario ``name``'s method flies phases (its own model and verification)."""
    return METHODS[str(get_scenario(name).problem["method"]["name"])].phases


def parser() -> argparse.ArgumentParser:
    """main()'s argument parser, apart so a test checks the documented commands against it."""
    cli = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cli.add_argument("--repeats", type=int, default=5)
    cli.add_argument("--only", nargs="*", default=None, help="scenario names (default: all)")
    cli.add_argument(
        "--nodes", nargs="*", type=int, default=None, help="node counts (default: each's own)"
    )
    return cli


def main() -> None:
    cli = parser()
    args = cli.parse_args()
    warm_up()
    names = args.only or [s.name for s in list_scenarios() if not _phased(s.name)]
    phased = [name for name in names if _phased(name)]
    if phased:
        cli.error(f"{', '.join(phased)}: a phased method's verification is timed by "
                  "bench.skip_table3")  # fmt: skip
    print(
        "| scenario | method | nodes | optimization s | verification s | verification / "
        "optimization | Python right-hand side s | its ratio | integrator steps | feasible |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, nodes in [(n, k) for n in names for k in (args.nodes or [None])]:
        row = bench(name, args.repeats, nodes)
        print(
            f"| {row['scenario']} | {row['method']} | {row['nodes']} | "
            f"{row['optimization_s']:.3f} | {row['verification_s']:.4f} | {row['ratio']:.3f} | "
            f"{row['python_rhs_s']:.3f} | {row['python_ratio']:.2f} | {row['steps']} | "
            f"{'yes' if row['feasible'] else 'no'} |"
        )


if __name__ == "__main__":
    main()
