"""foh-ptr case 1 (rlv-max-terminal-velocity) at every option's default across node counts.

Per node count and grid: status, iterations, wall time of the solve (the SCP loop and the
verification, after a warm-up of imports and compiled kernels), the time inside the conic
solves, the terminal velocity and its error against the NLP collocation optimum 971.03 m/s
(801 nodes), whether the verification found the trajectory feasible, and the largest
path-limit ratio between nodes.

    python -m bench.foh_meshes [--nodes 40 120 400] [--grids adaptive uniform]
"""

from __future__ import annotations

import argparse
import copy
import time

from app.schemas import ProblemDocument
from worker.solver.api import solve_problem
from worker.solver.scenarios import get_scenario

REFERENCE_VF_M_S = 971.03


def run(nodes: int, grid: str) -> dict[str, object]:
    """Case 1 with ``nodes`` and ``grid``, every other option at its default."""
    raw = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    raw["method"] = {**raw["method"], "nodes": nodes, "grid": grid}
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
        "error_pct": 100.0 * (vf / REFERENCE_VF_M_S - 1.0),
        "feasible": ver.get("feasible"),
        "path_ratio": max(ratios) if ratios else float("nan"),
    }


def main() -> None:
    """Print the table (markdown)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nodes", type=int, nargs="+", default=[40, 120, 400])
    parser.add_argument("--grids", nargs="+", default=["adaptive"])
    args = parser.parse_args()
    run(40, "adaptive")  # warm-up: imports, caches, compiled kernels
    print("| grid | nodes | status | iterations | wall s | conic s | Vf m/s | error % | feasible |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for grid in args.grids:
        for nodes in args.nodes:
            r = run(nodes, grid)
            print(
                f"| {r['grid']} | {r['nodes']} | {r['status']} | {r['iterations']} | "
                f"{r['wall_s']:.2f} | {r['conic_s']:.2f} | {r['vf']:.2f} | "
                f"{r['error_pct']:+.2f} | {r['feasible']} (path {r['path_ratio']:.3f}) |",
                flush=True,
            )


if __name__ == "__main__":
    main()
