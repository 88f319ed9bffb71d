"""The variant suite's table: every variant solved at default options against its reference.

Each row: the variant, its reference objective (independent NLP collocation, stored in
``tests/variants/data/``), the result's objective, the relative error, whether the verification
found the trajectory feasible, the status, SCP iterations and wall time of the whole solve. A
variant meets issue 15's acceptance when it succeeded, is verified feasible and lies within
0.3 % of its reference; a variant that reports ``succeeded`` outside that band is a wrong
answer and is flagged.

    python -m bench.variants [--only NAME ...] [--option METHOD.KEY=JSON ...]

``--option foh-ptr.weight_trust_interval=100`` sets that option for every variant of that method
(a sweep of a default over the suite); the other options stay as each variant gives them.
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

from app.schemas import ProblemDocument
from tests.variants.cases import TOLERANCE, Variant, relative_error, variants
from worker.solver.api import solve_problem

Overrides = dict[str, dict[str, Any]]


def parse_options(items: list[str]) -> Overrides:
    """``METHOD.KEY=JSON`` items as {method: {key: value}}."""
    found: Overrides = {}
    for item in items:
        name, _, value = item.partition("=")
        method, _, key = name.partition(".")
        if not key or not value:
            raise SystemExit(f"--option {item!r}: expected METHOD.KEY=JSON")
        found.setdefault(method, {})[key] = json.loads(value)
    return found


def run_variant(variant: Variant, overrides: Overrides | None = None) -> dict[str, Any]:
    """Solve one variant (with ``overrides`` of its method's options) against its reference."""
    doc = variant.document()
    extra = (overrides or {}).get(variant.method)
    if extra:
        raw = doc.model_dump(mode="json", exclude_unset=True)
        raw["method"] = {**raw["method"], **extra}
        doc = ProblemDocument.model_validate(raw)
    start = time.perf_counter()
    result = solve_problem(doc)
    wall = time.perf_counter() - start
    value = result.get("objective", {}).get("value")
    ref = variant.reference_objective
    error = relative_error(float(value), ref) if value is not None else float("nan")
    feasible = bool(result.get("verification", {}).get("feasible", False))
    status = str(result["status"])
    within = error <= TOLERANCE
    failure = result.get("failure") or {}
    return {
        "name": variant.name,
        "method": variant.method,
        "reference": ref,
        "value": value,
        "error_pct": 100.0 * error,
        "feasible": feasible,
        "status": status,
        "failure": failure.get("code", ""),
        "iterations": result.get("timing", {}).get("iterations", len(result.get("history", []))),
        "wall_s": wall,
        "meets": status == "succeeded" and feasible and within,
        "wrong": status == "succeeded" and not (feasible and within),
    }


def _fmt(value: Any) -> str:
    """A figure to 6 significant digits (``-`` when absent)."""
    return "-" if value is None else f"{float(value):.6g}"


def parser() -> argparse.ArgumentParser:
    """main()'s argument parser, apart so a test checks the documented commands against it."""
    cli = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cli.add_argument("--only", nargs="*", default=None, help="variant names (default: all)")
    cli.add_argument(
        "--option", nargs="*", default=[], metavar="METHOD.KEY=JSON", help="option overrides"
    )
    return cli


def main() -> None:
    args = parser().parse_args()
    overrides = parse_options(args.option)
    chosen = [v for v in variants() if args.only is None or v.name in args.only]
    print(
        "| variant | method | reference | result | error % | feasible | status | iterations "
        "| wall s | meets 0.3 % |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for variant in chosen:
        r = run_variant(variant, overrides)
        rows.append(r)
        status = r["status"] + (f" ({r['failure']})" if r["failure"] else "")
        verdict = "yes" if r["meets"] else ("WRONG ANSWER" if r["wrong"] else "no")
        print(
            f"| {r['name']} | {r['method']} | {_fmt(r['reference'])} | {_fmt(r['value'])} | "
            f"{r['error_pct']:.3f} | {'yes' if r['feasible'] else 'no'} | {status} | "
            f"{r['iterations']} | {r['wall_s']:.2f} | {verdict} |",
            flush=True,
        )
    meets = [r["name"] for r in rows if r["meets"]]
    wrong = [r["name"] for r in rows if r["wrong"]]
    print(f"\nmeet the acceptance ({len(meets)}/{len(rows)}): {', '.join(meets) or 'none'}")
    print(f"succeeded with a wrong answer: {', '.join(wrong) or 'none'}")


if __name__ == "__main__":
    main()
