"""How many iterations user-like problems take: the evidence for the default iteration budgets.

Paper 002's vehicle (the X-33-like RLV over a rotating Earth) from a user's entry point (10 E,
5 N, 95 km, 7 300 m/s) to targets of a user's own at 25 km, without a zone, minimizing the heat
load: energy-scp with a free final time and the terminal speed fixed at 900 m/s, foh-ptr with a
fixed final time inside the window the pre-checks' flights give for the target's distance. Each
problem is solved with an ample budget (``--max-iterations``, per start for foh-ptr) and the
table gives, per start, how many iterations it took: a default below that number turns the
problem into a failure by budget.

    python -m bench.iteration_budgets [--max-iterations 500] [--only energy-scp|foh-ptr]
"""

from __future__ import annotations

import argparse
import copy
import time
from collections.abc import Callable
from typing import Any

from app.schemas import ProblemDocument
from worker.solver.api import solve_problem
from worker.solver.scenarios import get_scenario

ENTRY = {
    "altitude_m": 95000,
    "longitude_deg": 10,
    "latitude_deg": 5,
    "velocity_m_s": 7300,
    "flight_path_angle_deg": 0,
}
TARGETS = (
    ((30.0, 55.0), 20.0, 1300.0),
    ((25.0, 50.0), 20.0, 1150.0),
    ((35.0, 45.0), 20.0, 1200.0),
    ((40.0, 50.0), 30.0, 1350.0),
    ((20.0, 60.0), 10.0, 1350.0),
)
"""(target longitude, latitude), entry heading, foh-ptr's final time (s)."""


def user_problem(
    method: str, target: tuple[float, float], heading: float, final_time_s: float
) -> dict[str, Any]:
    """The user-like problem for ``method`` (see the module docstring)."""
    doc = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    doc["initial_state"] = {**ENTRY, "heading_deg": heading}
    doc["terminal"] = {
        "altitude_m": 25000,
        "longitude_deg": target[0],
        "latitude_deg": target[1],
        "velocity_m_s": {"kind": "free"},
        "flight_path_angle_deg": {"kind": "free"},
        "heading_deg": {"kind": "free"},
    }
    doc["objective"] = "min_heat_load"
    if method == "energy-scp":
        doc["terminal"]["velocity_m_s"] = 900
        doc["final_time"] = {"kind": "free"}
        doc["control_limits"] = {"bank_max_deg": 80}
    else:
        doc["final_time"] = {"kind": "fixed", "value_s": final_time_s}
    doc["method"] = {"name": method}
    return doc


def main(argv: list[str] | None = None, out: Callable[[str], None] = print) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-iterations", type=int, default=500)
    parser.add_argument("--only", choices=("energy-scp", "foh-ptr"), default=None)
    args = parser.parse_args(argv)
    out(f"{'method':11} {'target':12} {'heading':>7} {'status':22} {'iterations':>18} {'CPU s':>6}")
    for method in ("energy-scp", "foh-ptr"):
        if args.only and method != args.only:
            continue
        for target, heading, final_time in TARGETS:
            doc = user_problem(method, target, heading, final_time)
            doc["method"]["max_iterations"] = args.max_iterations
            start = time.process_time()
            result = solve_problem(ProblemDocument.model_validate(doc))
            cpu = time.process_time() - start
            starts = result.get("starts") or []
            counts = (
                "+".join(str(s["iterations"]) for s in starts)
                if starts
                else str(len(result.get("history") or []))
            )
            code = (result.get("failure") or {}).get("code")
            status = result["status"] + (f" ({code})" if code else "")
            out(
                f"{method:11} {target[0]:4g} E {target[1]:3g} N {heading:7g} {status:22} "
                f"{counts:>18} {cpu:6.1f}"
            )


if __name__ == "__main__":
    main()
