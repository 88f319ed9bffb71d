"""The SCP methods against a general NLP solver on the same problems, side by side in one run.

For each problem: the SCP solve (the service's ``solve_problem``, warm: imports and compiled
kernels loaded by a first solve) with its optimization time (``timing.wall_s``) and its
verification time, and the NLP (``bench.nlp_collocation``: Hermite–Simpson collocation, IPOPT
through CasADi, built once, timed over IPOPT's solve alone from the same initial guess each
time), run in alternating pairs; medians of ``--repeats`` pairs and the ratios NLP / SCP. Both
objectives are printed against the independent reference, so a fast wrong answer shows.

    pip install -e '.[bench]'   # CasADi
    python -m bench.nlp_side_by_side [--repeats 5] [--only NAME ...] [--intervals N]

``--intervals`` sets the NLP's mesh (default: the SCP's node count minus one, the same number
of mesh nodes; Hermite–Simpson adds a midpoint per interval).
"""

from __future__ import annotations

import argparse
import copy
import statistics
from dataclasses import dataclass
from typing import Any

from app.schemas import ProblemDocument
from worker.solver.api import solve_problem
from worker.solver.scenarios import get_scenario


@dataclass(frozen=True)
class Problem:
    """One comparison: a built-in scenario and the reference optimum of its objective."""

    name: str
    scenario: str
    reference: float | None
    units: str


PROBLEMS = (
    Problem("paper 000 min heat load", "rlv-min-heat-load", 731.0102e6, "J/m^2"),
    Problem("paper 002 case 1", "rlv-max-terminal-velocity", 971.03, "m/s"),
    Problem("case 1 + an active zone", "rlv-max-terminal-velocity-active-nfz", None, "m/s"),
)
"""References: paper 000's NLP collocation (961 nodes) and paper 002 case 1's (801 nodes), both
in docs/methods; the active-zone scenario (a great-circle zone) has none: its two objectives
are compared with each other."""


def _scp(document: dict[str, Any]) -> dict[str, float]:
    result = solve_problem(ProblemDocument.model_validate(document))
    return {
        "optimization_s": float(result["timing"]["wall_s"]),
        "verification_s": float(result["timing"]["verification_s"]),
        "objective": float((result.get("objective") or {}).get("value") or float("nan")),
        "succeeded": result["status"] == "succeeded",
    }


def compare(problem: Problem, repeats: int, intervals: int | None) -> dict[str, Any]:
    """Run the SCP and the NLP on ``problem`` in ``repeats`` alternating pairs."""
    from bench.nlp_collocation import EntryNlp

    document = copy.deepcopy(get_scenario(problem.scenario).problem)
    nodes = int(document["method"].get("nodes", 40))
    nlp = EntryNlp(document, intervals or nodes - 1)
    _scp(document)  # warm: imports, caches, compiled kernels
    nlp.solve()  # warm: CasADi's function build, IPOPT's first call
    scp_runs, nlp_runs = [], []
    for _ in range(repeats):
        scp_runs.append(_scp(document))
        nlp_runs.append(nlp.solve())
    opt = statistics.median(r["optimization_s"] for r in scp_runs)
    total = statistics.median(r["optimization_s"] + r["verification_s"] for r in scp_runs)
    ipopt = statistics.median(r.solve_s for r in nlp_runs)
    last_nlp = nlp_runs[-1]
    return {
        "problem": problem.name,
        "scp_nodes": nodes,
        "nlp_intervals": nlp.n,
        "optimization_s": opt,
        "total_s": total,
        "nlp_s": ipopt,
        "nlp_over_opt": ipopt / opt,
        "nlp_over_total": ipopt / total,
        "scp_objective": scp_runs[-1]["objective"],
        "scp_succeeded": all(r["succeeded"] for r in scp_runs),
        "nlp_objective": last_nlp.objective,
        "nlp_status": last_nlp.status,
        "nlp_iterations": last_nlp.iterations,
        "reference": problem.reference,
        "units": problem.units,
    }


def _error(value: float, reference: float | None) -> str:
    if reference is None:
        return "no reference"
    return f"{100.0 * (value / reference - 1.0):+.2f} %"


def parser() -> argparse.ArgumentParser:
    """main()'s argument parser, apart so a test checks the documented commands against it."""
    cli = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cli.add_argument("--repeats", type=int, default=5, help="alternating pairs per problem")
    cli.add_argument("--only", nargs="*", default=None, help="scenario names")
    cli.add_argument("--intervals", type=int, default=None, help="NLP mesh intervals")
    return cli


def main() -> None:
    """Print the table (markdown)."""
    args = parser().parse_args()
    try:
        import casadi  # noqa: F401
    except ImportError:
        raise SystemExit("CasADi is needed: pip install -e '.[bench]'") from None
    print(
        "| problem | SCP nodes | NLP intervals | optimization s | + verification s | "
        "NLP (IPOPT solve) s | NLP / optimization | NLP / (opt + verif) | SCP objective | "
        "NLP objective (IPOPT status, iterations) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for problem in PROBLEMS:
        if args.only and problem.scenario not in args.only:
            continue
        r = compare(problem, args.repeats, args.intervals)
        ok = "" if r["scp_succeeded"] else " (not succeeded)"
        print(
            f"| {r['problem']} | {r['scp_nodes']} | {r['nlp_intervals']} | "
            f"{r['optimization_s']:.3f} | {r['total_s']:.3f} | {r['nlp_s']:.3f} | "
            f"{r['nlp_over_opt']:.1f} | {r['nlp_over_total']:.1f} | "
            f"{r['scp_objective']:.6g} ({_error(r['scp_objective'], r['reference'])}){ok} | "
            f"{r['nlp_objective']:.6g} ({_error(r['nlp_objective'], r['reference'])}; "
            f"{r['nlp_status']}, {r['nlp_iterations']}) |",
            flush=True,
        )


if __name__ == "__main__":
    main()
