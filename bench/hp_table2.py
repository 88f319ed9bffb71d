"""Paper 003's Table 2 repeated on this machine: its method against a uniform mesh and a general
NLP solver on the paper's case (``rlv-min-time-hp``), side by side in one run.

Rows: ``hp-scp`` at its defaults (adaptive h-refinement; the sliding-window reduction of the
paper is not built, so this is also its "hp without reduction"), with ``between_points`` staged,
and on a fixed uniform mesh (the paper's basic SCP); then the NLP (``bench.nlp_collocation``:
Hermite–Simpson on a uniform time mesh, IPOPT through CasADi, straight-line guess) at the given
interval counts. For each SCP row: status, mesh points at the end, iterations, optimization and
verification time, wall / sum of conic solve time, the propagated terminal errors and the final
time against the independent reference (1323.6 s, the best known optimum).

    pip install -e '.[bench]'   # CasADi
    python -m bench.hp_table2 [--uniform-nodes 201] [--nlp-intervals 100 ...]
"""

from __future__ import annotations

import argparse
import copy
from typing import Any

from app.schemas import ProblemDocument
from worker.solver.api import solve_problem
from worker.solver.scenarios import get_scenario

SCENARIO = "rlv-min-time-hp"
REFERENCE_TF_S = 1323.6
"""The shared independent reference (seed003_min_time, 250 intervals, mesh-converged)."""
TABLE2_ERRORS = {
    "altitude_m": 30.0,
    "velocity_m_s": 10.0,
    "longitude_deg": 0.01,
    "latitude_deg": 0.01,
    "flight_path_angle_deg": 0.05,
    "heading_deg": 0.05,
}
"""Paper 003 Table 2's terminal errors of its method (the acceptance's bounds)."""


def timing_cells(label: str, result: dict[str, Any]) -> dict[str, Any]:
    """A solved result's row cells shared by the tables: label, status, iterations,
    optimization and verification time, wall / sum of conic solve time."""
    timing = result["timing"]
    conic = timing.get("conic_solve_s")
    return {
        "label": label,
        "status": result["status"],
        "iterations": timing.get("iterations"),
        "optimization_s": timing.get("wall_s"),
        "verification_s": timing.get("verification_s"),
        "wall_over_conic": timing["wall_s"] / conic if conic else None,
    }


def scp_row(label: str, method: dict[str, Any]) -> dict[str, Any]:
    """One SCP solve of the scenario with ``method`` options."""
    document = copy.deepcopy(get_scenario(SCENARIO).problem)
    document["method"] = {"name": "hp-scp", **method}
    result = solve_problem(ProblemDocument.model_validate(document))
    history = result.get("history") or [{}]
    verification = result.get("verification") or {}
    errors = {
        key: entry["error"]
        for key, entry in (verification.get("terminal_error_vs_target") or {}).items()
    }
    tf = (result.get("objective") or {}).get("value")
    return {
        **timing_cells(label, result),
        "points": history[-1].get("extra", {}).get("mesh_points"),
        "errors": errors,
        "tf_s": tf,
        "verified": bool(verification.get("feasible")),
    }


def nlp_row(intervals: int) -> dict[str, Any]:
    """One NLP solve (IPOPT's solve time; the build is not counted)."""
    from bench.nlp_collocation import EntryNlp

    document = copy.deepcopy(get_scenario(SCENARIO).problem)
    nlp = EntryNlp(document, intervals, max_iter=3000, linear_guess=True)
    solution = nlp.solve()
    return {
        "label": f"NLP, Hermite-Simpson, {intervals} intervals",
        "status": solution.status,
        "points": 2 * intervals + 1,
        "iterations": solution.iterations,
        "optimization_s": solution.solve_s,
        "verification_s": None,
        "wall_over_conic": None,
        "errors": {},
        "tf_s": solution.objective,
        "verified": None,
    }


def cell(value: Any, fmt: str = "{:.3g}") -> str:
    """A table cell: ``fmt`` for a float, a dash when absent."""
    if value is None:
        return "—"
    if isinstance(value, float):
        return fmt.format(value)
    return str(value)


def table(rows: list[dict[str, Any]]) -> str:
    """The rows as a Markdown table."""
    names = list(TABLE2_ERRORS)
    head = (
        "| run | status | points | iterations | optimization s | verification s | wall / conic "
        "| "
        + " | ".join(f"{n} (≤ {TABLE2_ERRORS[n]:g})" for n in names)
        + " | tf s | vs 1323.6 s |"
    )
    lines = [head, "|" + "---|" * (10 + len(names))]
    for row in rows:
        tf = row["tf_s"]
        off = None if tf is None else 100.0 * (tf / REFERENCE_TF_S - 1.0)
        errors = [cell(row["errors"].get(n), "{:.2g}") for n in names]
        lines.append(
            f"| {row['label']} | {row['status']} | {cell(row['points'])} | "
            f"{cell(row['iterations'])} | {cell(row['optimization_s'], '{:.2f}')} | "
            f"{cell(row['verification_s'], '{:.2f}')} | "
            f"{cell(row['wall_over_conic'], '{:.2f}')} | "
            + " | ".join(errors)
            + f" | {cell(tf, '{:.2f}')} | {cell(off, '{:+.2f} %')} |"
        )
    return "\n".join(lines)


def parser() -> argparse.ArgumentParser:
    """main()'s argument parser, apart so a test checks the documented commands against it."""
    cli = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cli.add_argument("--uniform-nodes", type=int, default=201)
    cli.add_argument("--nlp-intervals", type=int, nargs="*", default=[100])
    return cli


def main() -> None:
    cli = parser()
    args = cli.parse_args()
    uniform = args.uniform_nodes
    if (uniform - 1) % 5:
        cli.error("--uniform-nodes must be 5 k + 1 (intervals of degree 5)")
    rows = [
        scp_row("hp-scp, defaults (adaptive h)", {}),
        scp_row("hp-scp, between_points staged", {"between_points": "staged"}),
        scp_row(
            f"hp-scp, uniform fixed mesh, {uniform} points",
            {"mesh": "fixed", "nodes": uniform, "intervals": (uniform - 1) // 5},
        ),
    ]
    rows.extend(nlp_row(n) for n in args.nlp_intervals)
    print(table(rows))


if __name__ == "__main__":
    main()
