"""foh-ptr case 1 (rlv-max-terminal-velocity) at every option's default across node counts.

Per node count and grid: status, iterations, wall time of the solve (the SCP loop and the
verification, after a warm-up of imports and compiled kernels), the time inside the conic
solves, the terminal velocity and its error against the NLP collocation optimum 971.03 m/s
(801 nodes), whether the verification found the trajectory feasible, and the largest
path-limit ratio between nodes; with ``--variant`` a foh-ptr case of the variant suite
(``tests/variants``) against its own reference instead; with ``--method KEY=JSON`` an option
set for every run (e.g. ``bank_sign_starts=false``).

    python -m bench.foh_meshes [--nodes 40 120 400] [--grids adaptive uniform]
        [--variant foh-active-nfz] [--method KEY=JSON ...]
"""

from __future__ import annotations

import argparse
import copy
import json
import time
from typing import Any

from app.schemas import ProblemDocument
from worker.solver.api import solve_problem
from worker.solver.scenarios import get_scenario

REFERENCE_VF_M_S = 971.03


def _case(variant: str | None) -> tuple[dict[str, Any], float]:
    """The problem document and its reference objective: case 1, or a variant of the suite."""
    if variant is None:
        return copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem), REFERENCE_VF_M_S
    from tests.variants.cases import variants

    found = [v for v in variants() if v.name == variant]
    if not found:
        raise SystemExit(f"unknown variant {variant!r}")
    doc = found[0].document().model_dump(mode="json", exclude_unset=True)
    return doc, found[0].reference_objective


def run(
    nodes: int,
    grid: str,
    variant: str | None = None,
    method: dict[str, Any] | None = None,
) -> dict[str, object]:
    """The case with ``nodes``, ``grid`` and ``method`` options, every other at its default."""
    raw, reference = _case(variant)
    raw["method"] = {**raw["method"], **(method or {}), "nodes": nodes, "grid": grid}
    start = time.perf_counter()
    result = solve_problem(ProblemDocument.model_validate(raw))
    wall = time.perf_counter() - start
    vf = float(result["objective"]["value"]) if result.get("objective") else float("nan")
    ver = result.get("verification") or {}
    ratios = [entry["ratio"] for entry in (ver.get("path_maxima") or {}).values()]
    return {
        "nodes": nodes,
        "grid": grid,
        "status": result["status"],
        "iterations": result["timing"]["iterations"],
        "wall_s": wall,
        "conic_s": result["timing"].get("conic_solve_s", float("nan")),
        "vf": vf,
        "error_pct": 100.0 * (vf / reference - 1.0),
        "starts": " / ".join(
            f"{s['initial_bank_deg']:+g}: {next(iter(s['objective_terms'].values()), 0.0):.2f}"
            for s in result.get("starts") or []
        ),
        "feasible": ver.get("feasible"),
        "path_ratio": max(ratios) if ratios else float("nan"),
    }


def parser() -> argparse.ArgumentParser:
    """main()'s argument parser, apart so a test checks the documented commands against it."""
    cli = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cli.add_argument("--nodes", type=int, nargs="+", default=[40, 120, 400])
    cli.add_argument("--grids", nargs="+", default=["adaptive"])
    cli.add_argument("--variant", default=None, help="a foh-ptr variant of tests/variants")
    cli.add_argument("--method", nargs="*", default=[], metavar="KEY=JSON")
    return cli


def main() -> None:
    """Print the table (markdown)."""
    args = parser().parse_args()
    method = {k: json.loads(v) for k, v in (item.split("=", 1) for item in args.method)}
    run(40, "adaptive")  # warm-up: imports, caches, compiled kernels
    print(
        "| grid | nodes | status | iterations | wall s | conic s | objective | error % | "
        "feasible | starts (initial bank: objective) |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for grid in args.grids:
        for nodes in args.nodes:
            r = run(nodes, grid, args.variant, method)
            print(
                f"| {r['grid']} | {r['nodes']} | {r['status']} | {r['iterations']} | "
                f"{r['wall_s']:.2f} | {r['conic_s']:.2f} | {r['vf']:.2f} | "
                f"{r['error_pct']:+.2f} | {r['feasible']} (path {r['path_ratio']:.3f}) | "
                f"{r['starts']} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
