"""Benchmark of the energy-domain SCP on the rlv-min-heat-load scenario.

Reports, per node count, medians over repeated solves in one process: wall time of the
optimization (the SCP loop), the sum of the time inside Clarabel's ``solve``, their ratio (the
cost of everything that is not the conic solver), the same ratio with the time inside
Clarabel's own constructor and ``update()`` (its setup work) also counted as conic time,
iterations, and the verification time. Ratios inside one run are robust to a shared, noisy
machine; absolute times are not.

    python -m bench.energy_scp --repeats 7 --nodes 41 121 401
"""

from __future__ import annotations

import argparse
import statistics
import time

from app.schemas import ProblemDocument
from worker.solver.methods.energy_scp.method import run as run_energy_scp
from worker.solver.problem import build_problem
from worker.solver.scenarios import get_scenario
from worker.solver.verification import verify


def _document(nodes: int) -> ProblemDocument:
    raw = dict(get_scenario("rlv-min-heat-load").problem)
    raw["method"] = {**raw["method"], "nodes": nodes}
    return ProblemDocument.model_validate(raw)


def bench(nodes: int, repeats: int) -> dict[str, float]:
    """Median figures of ``repeats`` solves at ``nodes`` nodes (after one warm-up solve)."""
    doc = _document(nodes)
    model = build_problem(doc)
    run_energy_scp(model, doc.method)  # warm-up: imports, caches
    walls, conics, inside, iters = [], [], [], []
    outcome = None
    for _ in range(repeats):
        start = time.perf_counter()
        outcome = run_energy_scp(model, doc.method)
        walls.append(time.perf_counter() - start)
        conics.append(outcome.conic_solve_s)
        inside.append(outcome.conic_solve_s + sum(r.conic_solver_setup_s for r in outcome.history))
        iters.append(len(outcome.history))
    assert outcome is not None and outcome.trajectory is not None
    v_start = time.perf_counter()
    report = verify(model, outcome.trajectory)
    verification = time.perf_counter() - v_start
    ratios = [w / c for w, c in zip(walls, conics, strict=True)]
    ratios_inside = [w / c for w, c in zip(walls, inside, strict=True)]
    return {
        "nodes": nodes,
        "status": outcome.status,
        "iterations": statistics.median(iters),
        "wall_s": statistics.median(walls),
        "conic_s": statistics.median(conics),
        "ratio": statistics.median(ratios),
        "ratio_inside": statistics.median(ratios_inside),
        "per_iteration_ms": 1e3 * statistics.median(walls) / statistics.median(iters),
        "verification_s": verification,
        "feasible": report["feasible"],
    }


def parser() -> argparse.ArgumentParser:
    """main()'s argument parser, apart so a test checks the documented commands against it."""
    cli = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cli.add_argument("--repeats", type=int, default=7)
    cli.add_argument("--nodes", type=int, nargs="+", default=[41, 121, 401])
    return cli


def main() -> None:
    args = parser().parse_args()
    print(
        "| nodes | status | iterations | wall s (median) | conic s | wall/conic "
        "| wall/(conic incl. Clarabel setup) | ms/iteration | verification s | verified |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for n in args.nodes:
        r = bench(n, args.repeats)
        print(
            f"| {r['nodes']} | {r['status']} | {r['iterations']:g} | {r['wall_s']:.3f} | "
            f"{r['conic_s']:.3f} | {r['ratio']:.2f} | {r['ratio_inside']:.2f} | "
            f"{r['per_iteration_ms']:.1f} | "
            f"{r['verification_s']:.2f} | {r['feasible']} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
