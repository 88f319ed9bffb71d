"""Paper 001's Table 2 repeated on this machine: the Chebyshev SCvx at the paper's point counts
(one interval), at its defaults, an equally spaced SCvx and a general NLP solver on the paper's
case (``cav-h-min-time``), side by side in one run.

Rows: ``cheb-scvx`` on one Chebyshev interval at 25/30/40/60 points (the paper's Cheb-SCvx);
at its defaults (201 points on 20 intervals); with 79 and 299 intervals of the method's lowest
degree, 2 (159 and 599 equally spaced points, Simpson's rule: the paper's Eq-SCvx); then the NLP
(``bench.nlp_collocation``: Hermite-Simpson on a uniform time mesh, IPOPT through CasADi) at
the given interval counts. For each SCP row: status, iterations, optimization and verification
time, wall / sum of conic solve time, the propagated terminal flight-path-angle error, the final
time against the independent reference (2694.62 s), and the NLP's solve time over the row's
optimization + verification.

    pip install -e '.[bench]'   # CasADi
    python -m bench.cheb_table2 [--nlp-intervals 100 ...]
"""

from __future__ import annotations

import argparse
import copy
from typing import Any

from app.schemas import ProblemDocument
from bench.hp_table2 import cell, timing_cells
from worker.solver.api import solve_problem
from worker.solver.scenarios import get_scenario

SCENARIO = "cav-h-min-time"
REFERENCE_TF_S = 2694.62
"""The shared independent reference (seed001_cavh_min_time, 400 intervals, mesh-converged)."""


def scp_row(label: str, method: dict[str, Any]) -> dict[str, Any]:
    """One cheb-scvx solve of the scenario with ``method`` options."""
    document = copy.deepcopy(get_scenario(SCENARIO).problem)
    document["method"] = {"name": "cheb-scvx", **method}
    result = solve_problem(ProblemDocument.model_validate(document))
    verification = result.get("verification") or {}
    terminal = verification.get("terminal_error_vs_target") or {}
    return {
        **timing_cells(label, result),
        "gamma_error_deg": (terminal.get("flight_path_angle_deg") or {}).get("error"),
        "tf_s": (result.get("objective") or {}).get("value"),
    }


def nlp_row(intervals: int) -> dict[str, Any]:
    """One NLP solve (IPOPT's solve time; the build is not counted)."""
    from bench.nlp_collocation import EntryNlp

    document = copy.deepcopy(get_scenario(SCENARIO).problem)
    solution = EntryNlp(document, intervals, max_iter=3000).solve()
    return {
        "label": f"NLP, Hermite-Simpson, {intervals} intervals",
        "status": solution.status,
        "iterations": solution.iterations,
        "optimization_s": solution.solve_s,
        "verification_s": None,
        "wall_over_conic": None,
        "gamma_error_deg": None,
        "tf_s": solution.objective,
    }


def table(rows: list[dict[str, Any]], nlp_s: float | None) -> str:
    """The rows as a Markdown table; ``nlp_s``: the first NLP row's solve time."""
    lines = [
        "| run | status | iterations | optimization s | verification s | wall / conic "
        "| terminal gamma error deg | tf s | vs 2694.62 s | NLP s / (opt + verif) s |",
        "|" + "---|" * 10,
    ]
    for row in rows:
        tf = row["tf_s"]
        off = None if tf is None else 100.0 * (tf / REFERENCE_TF_S - 1.0)
        total = (row["optimization_s"] or 0.0) + (row["verification_s"] or 0.0)
        speed = nlp_s / total if nlp_s and row["verification_s"] is not None else None
        lines.append(
            f"| {row['label']} | {row['status']} | {cell(row['iterations'])} | "
            f"{cell(row['optimization_s'], '{:.2f}')} | "
            f"{cell(row['verification_s'], '{:.2f}')} | "
            f"{cell(row['wall_over_conic'], '{:.2f}')} | "
            f"{cell(row['gamma_error_deg'], '{:+.3f}')} | "
            f"{cell(tf, '{:.2f}')} | {cell(off, '{:+.3f} %')} | {cell(speed, '{:.2f}')} |"
        )
    return "\n".join(lines)


def parser() -> argparse.ArgumentParser:
    """main()'s argument parser, apart so a test checks the documented commands against it."""
    cli = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cli.add_argument("--nlp-intervals", type=int, nargs="*", default=[100])
    return cli


def main() -> None:
    args = parser().parse_args()
    rows = [
        scp_row(f"cheb-scvx, one interval, {n} points", {"nodes": n, "intervals": 1})
        for n in (25, 30, 40, 60)
    ]
    rows.append(scp_row("cheb-scvx, defaults (201 points, 20 intervals)", {}))
    rows.extend(
        scp_row(
            f"equally spaced SCvx ({k} intervals of degree 2), {2 * k + 1} points",
            {"nodes": 2 * k + 1, "intervals": k},
        )
        for k in (79, 299)
    )
    nlp = [nlp_row(n) for n in args.nlp_intervals]
    print(table(rows + nlp, nlp[0]["optimization_s"] if nlp else None))


if __name__ == "__main__":
    main()
