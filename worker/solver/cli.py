"""Command-line front end of the solver core: ``trajopt scenarios`` and ``trajopt solve``.

Runs in-process with no service, broker or database. Exit codes: 0 solved and verified,
1 the solve failed (reason printed), 2 the problem was invalid or could not be read.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from app.schemas import ProblemDocument, issues_from_validation_error
from worker.solver.api import solve_problem
from worker.solver.methods import check_support
from worker.solver.scenarios import get_scenario, list_scenarios


def _load(source: str) -> dict[str, Any]:
    path = Path(source)
    if path.suffix == ".json" or path.exists():
        raw = json.loads(path.read_text(encoding="utf-8"))
        if isinstance(raw, dict) and "problem" in raw and "vehicle" not in raw:
            raw = raw["problem"]  # a scenario file
        if not isinstance(raw, dict):
            raise ValueError(f"{source}: a problem document must be a JSON object")
        return raw
    return dict(get_scenario(source).problem)


def _progress(record: dict[str, Any]) -> None:
    change = record["max_state_change"]
    value = record.get("objective_value")
    shown = f"{value:.6g}" if isinstance(value, float) else "-"
    print(
        f"iter {record['iteration']:3d}  objective {shown:>12}  "
        f"dh {change['altitude_m']:9.1f} m  dlon {change['longitude_deg']:7.3f}  "
        f"dlat {change['latitude_deg']:7.3f}  dgam {change['flight_path_angle_deg']:6.3f}  "
        f"dpsi {change['heading_deg']:6.3f} deg  {record['conic_status']}  "
        f"{1e3 * record['conic_solve_s']:6.1f} ms",
        file=sys.stderr,
        flush=True,
    )


def _summary(result: dict[str, Any]) -> str:
    lines = [f"status: {result['status']}"]
    if result.get("failure"):
        lines.append(f"reason: {result['failure']['code']}: {result['failure']['message']}")
    obj = result.get("objective")
    if obj and obj.get("value") is not None:
        lines.append(f"objective {obj['name']}: {obj['value']:.6g} {obj['units']}")
    ver = result.get("verification")
    if ver:
        lines.append(f"verification feasible: {ver['feasible']}")
        for name, entry in ver["terminal_error_vs_target"].items():
            lines.append(f"  terminal {name}: error {entry['error']:+.4g} ({entry['kind']})")
        for name, entry in ver["path_maxima"].items():
            if "limit" in entry:
                lines.append(f"  {name}: max {entry['max']:.6g} of limit {entry['limit']:.6g}")
    t = result["timing"]
    lines.append(
        f"iterations {t['iterations']}, optimization {t['wall_s']:.3f} s "
        f"(conic {t['conic_solve_s']:.3f} s), verification {t['verification_s']:.3f} s"
    )
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run the ``scenarios`` or ``solve`` subcommand; returns the exit code."""
    if args.command == "scenarios":
        for s in list_scenarios():
            print(f"{s.name:32s} {s.title}")
            print(f"{'':32s} source: {s.source}")
        return 0
    try:
        raw = _load(args.problem)
    except (OSError, ValueError, KeyError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.method or args.nodes is not None:
        method = dict(raw.get("method") or {})
        if args.method and method.get("name") != args.method:
            method = {"name": args.method}
        if args.nodes is not None:
            method["nodes"] = args.nodes
        raw["method"] = method
    try:
        doc = ProblemDocument.model_validate(raw)
    except ValidationError as exc:
        print("error: invalid problem:", file=sys.stderr)
        for issue in issues_from_validation_error(exc):
            print(f"  {issue.field}: {issue.message}", file=sys.stderr)
        return 2
    issues = check_support(doc)
    if issues:
        print(f"error: method {doc.method.name} cannot solve this problem:", file=sys.stderr)
        for issue in issues:
            print(f"  {issue.field}: {issue.message}", file=sys.stderr)
        return 2
    result = solve_problem(doc, on_iteration=None if args.quiet else _progress)
    if args.output:
        Path(args.output).write_text(json.dumps(result, indent=1), encoding="utf-8")
        print(f"result written to {args.output}", file=sys.stderr)
    print(_summary(result))
    return 0 if result["status"] == "succeeded" else 1
