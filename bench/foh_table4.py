"""Paper 002 Table 4 repeated: adaptive vs uniform exact FOH vs uniform trapezoid, case 1.

Per configuration: the step (the default SQP step with the maps' curvature, or paper 002's
first-order PTR step with the damping it needs, ``FIRST_ORDER``; the trapezoidal maps have no
curvature term), status, iterations, wall time of the SCP loop, sum of conic solve times, their
ratio, the same ratio with Clarabel's own setup work (its data ``update()``) counted as conic
time too, terminal velocity, the propagated terminal residuals (verification's
terminal_error_vs_optimized) and the largest path-limit ratio between nodes. Times are medians of
``--repeats`` solves after a warm-up (imports, caches, compiled kernels), each ratio taken per
solve and then its median; absolute times depend on the machine, ratios much less.

    python -m bench.foh_table4 [--repeats 7]
"""

from __future__ import annotations

import argparse
import statistics
import time

from app.schemas import ProblemDocument
from worker.solver.methods.foh_ptr.method import run as run_foh_ptr
from worker.solver.problem import build_problem
from worker.solver.scenarios import get_scenario
from worker.solver.verification import verify

FIRST_ORDER = {
    "second_order": False,
    "weight_nonlinear": 1.0e4,
    "weight_trust_region_min": 0.02,
    "trust_defect_target": 0.3,
    "trust_factor": 2.0,
}
"""The first-order PTR step as paper 002 takes it, with the eq. 26 penalty and a trust-weight
floor: without them its iterates oscillate (docs/methods/foh-ptr.md)."""

CONFIGS = (
    [("adaptive", "exact_foh", "sqp", n) for n in (40, 50, 60)]
    + [("uniform", "exact_foh", "sqp", n) for n in (40, 50, 60)]
    + [("adaptive", "exact_foh", "first-order", 40), ("uniform", "exact_foh", "first-order", 40)]
    + [("uniform", "trapezoid", "first-order", n) for n in (200, 300, 400)]
)


GUESSES_DEG = (-10.0, 0.0, 10.0, 20.0, 30.0)
"""Constant banks of the initial reference for ``--guesses`` (the sweep picks +20 deg)."""


def run(
    grid: str,
    discretization: str,
    step: str,
    nodes: int,
    bank_deg: float | None = None,
    repeats: int = 1,
) -> dict[str, object]:
    """Case 1 with the given grid, discretization, step, node count and guess, solved
    ``repeats`` times (median wall time and ratios)."""
    raw = dict(get_scenario("rlv-max-terminal-velocity").problem)
    raw["method"] = {
        "name": "foh-ptr",
        "nodes": nodes,
        "grid": grid,
        "discretization": discretization,
        "initial_bank_deg": bank_deg,
        **(FIRST_ORDER if step == "first-order" else {}),
    }
    doc = ProblemDocument.model_validate(raw)
    model = build_problem(doc)
    walls, conics, ratios, ratios_inside = [], [], [], []
    for _ in range(repeats):
        start = time.perf_counter()
        out = run_foh_ptr(model, doc.method)
        wall = time.perf_counter() - start
        inside = out.conic_solve_s + sum(r.conic_solver_setup_s for r in out.history)
        walls.append(wall)
        conics.append(out.conic_solve_s)
        ratios.append(wall / out.conic_solve_s)
        ratios_inside.append(wall / inside)
    assert out.trajectory is not None
    rep = verify(model, out.trajectory)
    err = rep["terminal_error_vs_optimized"]
    ratio = max(v["ratio"] for v in rep["path_maxima"].values() if "ratio" in v)
    return {
        "status": out.status,
        "iterations": len(out.history),
        "wall": statistics.median(walls),
        "conic": statistics.median(conics),
        "ratio": statistics.median(ratios),
        "ratio_inside": statistics.median(ratios_inside),
        "vf": out.objective_terms.get("max_terminal_velocity", float("nan")),
        "err": err,
        "path": ratio,
    }


def parser() -> argparse.ArgumentParser:
    """main()'s argument parser, apart so a test checks the documented commands against it."""
    cli = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cli.add_argument("--only", choices=("adaptive", "uniform", "trapezoid"), default=None)
    cli.add_argument(
        "--guesses",
        action="store_true",
        help="instead: 40 nodes, both grids, from each constant-bank guess of GUESSES_DEG",
    )
    cli.add_argument("--repeats", type=int, default=7, help="solves per configuration")
    return cli


def main() -> None:
    args = parser().parse_args()
    run("uniform", "exact_foh", "sqp", 40)  # warm-up
    if args.guesses:
        print("| grid | initial bank deg | status | iterations | wall s | Vf m/s |")
        print("|---" * 6 + "|")
        for grid in ("adaptive", "uniform"):
            for bank in GUESSES_DEG:
                r = run(grid, "exact_foh", "sqp", 40, bank)
                print(
                    f"| {grid} | {bank:+.0f} | {r['status']} | {r['iterations']} | "
                    f"{r['wall']:.3f} | {r['vf']:.1f} |",
                    flush=True,
                )
        return
    print(
        "| grid | discretization | step | nodes | status | iterations | wall s | conic s "
        "| wall/conic | wall/(conic + Clarabel setup) | Vf m/s | dr m | dlon deg | dlat deg "
        "| dV m/s | dgamma deg | dpsi deg | path max ratio |"
    )
    print("|---" * 18 + "|")
    for grid, disc, step, nodes in CONFIGS:
        key = "trapezoid" if disc == "trapezoid" else grid
        if args.only is not None and key != args.only:
            continue
        r = run(grid, disc, step, nodes, repeats=args.repeats)
        e = r["err"]
        assert isinstance(e, dict)
        print(
            f"| {grid} | {disc} | {step} | {nodes} | {r['status']} | {r['iterations']} | "
            f"{r['wall']:.3f} | {r['conic']:.3f} | {r['ratio']:.2f} | {r['ratio_inside']:.2f} | "
            f"{r['vf']:.1f} | {abs(e['altitude_m']):.2f} | {abs(e['longitude_deg']):.4f} | "
            f"{abs(e['latitude_deg']):.4f} | {abs(e['velocity_m_s']):.3f} | "
            f"{abs(e['flight_path_angle_deg']):.4f} | {abs(e['heading_deg']):.4f} | "
            f"{r['path']:.3f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
