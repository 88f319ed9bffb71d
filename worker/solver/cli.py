"""Command-line front end of the solver core: ``trajopt scenarios`` and ``trajopt solve``.

Runs in-process with no service, broker or database. Exit codes: 0 solved and verified,
1 the solve failed (reason printed), 2 the problem or the output path was invalid or could not
be read or written. Every refusal is one ``error: …`` line on stderr (one per issue for an
invalid document), checked before any work starts.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from worker.solver import FIRST_COMPILE
from worker.solver.scenarios import (
    Scenario,
    UnknownScenarioError,
    get_scenario,
    list_scenarios,
    shown_name,
)

if TYPE_CHECKING:
    from app.schemas import FieldIssue

MAX_ISSUE_LINES = 10
"""Issues of an invalid document printed at most; the rest are counted in one more line."""


class InputError(Exception):
    """Input the command refuses (exit 2); the message is one line naming the thing and why."""


def looks_like_path(source: str) -> bool:
    """Whether ``source`` is meant as a file rather than a scenario name."""
    separators = {"/", os.sep, os.altsep or "/"}
    return source.endswith(".json") or any(sep in source for sep in separators)


def _json_kind(value: Any) -> str:
    """How a JSON value is named in a message ("an array", "a number", ...)."""
    if isinstance(value, list):
        return "an array"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int | float):
        return "a number"
    return "null" if value is None else type(value).__name__


def os_reason(exc: OSError) -> str:
    """The short reason of an ``OSError`` (``No such file or directory``), without the path."""
    return exc.strerror or str(exc) or type(exc).__name__


def read_json_file(source: str, what: str) -> Any:
    """The JSON value in the file ``source``; InputError in one line (``what`` names the kind of
    file a directory is not) when it cannot be read or decoded."""
    path = Path(source)
    if _is(path, "is_dir"):
        raise InputError(f"{source} is a directory, not {what}")
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"no such file: {source}") from None
    except PermissionError:
        raise InputError(f"cannot read {source}: permission denied") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"{source}: not UTF-8 text (byte {exc.start})") from None
    except OSError as exc:
        raise InputError(f"cannot read {source}: {os_reason(exc)}") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(
            f"{source}: invalid JSON at line {exc.lineno} column {exc.colno}: {exc.msg}"
        ) from None
    except RecursionError:
        raise InputError(f"{source}: invalid JSON: nested too deeply") from None


def read_problem_file(source: str) -> dict[str, Any]:
    """The problem document in the file ``source`` (a scenario file gives its ``problem``)."""
    raw = read_json_file(source, "a problem file")
    if isinstance(raw, dict) and "problem" in raw and "vehicle" not in raw:
        raw = raw["problem"]  # a scenario file
        if not isinstance(raw, dict):
            raise InputError(f'{source}: "problem" must be a JSON object, not {_json_kind(raw)}')
    if not isinstance(raw, dict):
        raise InputError(
            f"{source}: a problem document must be a JSON object, not {_json_kind(raw)}"
        )
    return raw


def unknown_scenario_message(exc: UnknownScenarioError) -> str:
    """The command line's one-line answer to a scenario name that does not exist."""
    message = f"unknown scenario {shown_name(exc.name)!r}"
    if exc.suggestions:
        message += "; did you mean " + " or ".join(repr(s) for s in exc.suggestions) + "?"
    return message + " (`trajopt scenarios` lists them)"


def _is(path: Path, test: str) -> bool:
    """``path.is_file()`` / ``is_dir()`` / ``exists()``, False for a name the OS refuses."""
    try:
        return bool(getattr(path, test)())
    except (OSError, ValueError):  # e.g. a name too long
        return False


def load_problem(source: str) -> dict[str, Any]:
    """The document named by ``source``: a problem or scenario file, else a built-in scenario.

    A name that looks like a path (ends in ``.json`` or has a slash) is always a file, so a
    missing one is "no such file" rather than an unknown scenario.
    """
    path = Path(source)
    if looks_like_path(source) or _is(path, "is_file"):
        return read_problem_file(source)
    try:
        return dict(get_scenario(source).problem)
    except UnknownScenarioError as exc:
        if _is(path, "is_dir"):
            raise InputError(f"{source} is a directory, not a problem file") from None
        raise InputError(unknown_scenario_message(exc)) from None


def check_output(output: str) -> None:
    """Refuse an output path the result could not be written to, before any solving."""
    path = Path(output)
    if _is(path, "is_dir"):
        raise InputError(f"output {output} is a directory; give a file name")
    if _is(path, "exists"):
        if not os.access(path, os.W_OK):
            raise InputError(f"cannot write output {output}: permission denied")
        return
    parent = path.parent
    if not _is(parent, "exists"):
        raise InputError(f"cannot write output {output}: directory {parent} does not exist")
    if not _is(parent, "is_dir"):
        raise InputError(f"cannot write output {output}: {parent} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"cannot write output {output}: no permission to create files in {parent}")


def write_text(output: str, text: str, what: str) -> None:
    """Write ``text`` to ``output``; ``InputError`` naming ``what`` and the reason on failure."""
    try:
        with open(output, "w", encoding="utf-8") as handle:
            handle.write(text)
    except OSError as exc:
        raise InputError(f"cannot write {what} to {output}: {os_reason(exc)}") from None


def write_result(output: str, result: dict[str, Any]) -> None:
    """Write the result document to ``output``; ``InputError`` with the reason when it fails."""
    write_text(output, json.dumps(result, indent=1), "the result")


def issue_lines(prefix: str, issues: Sequence[FieldIssue]) -> list[str]:
    """One ``error:`` line per issue (at most ``MAX_ISSUE_LINES``, then a count of the rest)."""
    lines = [
        f"error: {prefix}: {issue.field}: {issue.message}"
        if issue.field
        else f"error: {prefix}: {issue.message}"
        for issue in issues[:MAX_ISSUE_LINES]
    ]
    if len(issues) > MAX_ISSUE_LINES:
        lines.append(f"error: {prefix}: and {len(issues) - MAX_ISSUE_LINES} more issues")
    return lines


def scenario_table(scenarios: Sequence[Scenario]) -> list[str]:
    """The scenarios as an aligned table (widths from the data), each source under its title."""
    header = ("NAME", "METHOD", "NODES", "TITLE")
    rows = [header]
    for s in scenarios:
        method = s.problem.get("method") or {}
        rows.append((s.name, str(method.get("name", "-")), str(method.get("nodes", "-")), s.title))
    widths = [max(len(row[i]) for row in rows) for i in range(len(header) - 1)]
    indent = sum(widths) + 2 * len(widths)
    lines = []
    for i, row in enumerate(rows):
        cells = [
            row[0].ljust(widths[0]),
            row[1].ljust(widths[1]),
            row[2].rjust(widths[2]),
            row[3],
        ]
        lines.append("  ".join(cells))
        if i:
            lines.append(" " * indent + f"source: {scenarios[i - 1].source}")
    return lines


def _kernels_notice(wait: str, *, quiet: bool = False) -> None:
    """Say on stderr why the solve waits before its first iteration: the first after an install
    compiles the solver's kernels (said even with --quiet: a minute's silence reads as a hang);
    a load from numba's cache is said only when it is slow, and not with --quiet."""
    if wait == "compiling":
        line = (
            f"compiling the solver's kernels: once after an install, {FIRST_COMPILE} "
            "(python -m worker.solver.warmup does it ahead of time)"
        )
    elif quiet:
        return
    else:
        line = "loading the solver's compiled kernels from numba's cache"
    print(line, file=sys.stderr, flush=True)


def _progress(record: dict[str, Any]) -> None:
    """One progress line per SCP iteration (or generation of a global search) on stderr."""
    extra = record.get("extra") or {}
    if extra.get("stage") == "global_guess":
        print(
            f"guess {extra['algorithm']} generation {extra['generation']:3d}  best score "
            f"{extra['best_score']:.6g}",
            file=sys.stderr,
            flush=True,
        )
        return
    attempt = f"{extra['method']:10s} " if extra.get("auto_attempt") else ""  # auto's attempt
    change = record["max_state_change"]
    value = record.get("objective_value")
    shown = f"{value:.6g}" if isinstance(value, float) else "-"
    if not change:  # the first iteration of a method that reports changes between iterates
        change = dict.fromkeys(
            ("altitude_m", "longitude_deg", "latitude_deg", "flight_path_angle_deg", "heading_deg"),
            0.0,
        )
    print(
        f"{attempt}iter {record['iteration']:3d}  objective {shown:>12}  "
        f"dh {change['altitude_m']:9.1f} m  dlon {change['longitude_deg']:7.3f}  "
        f"dlat {change['latitude_deg']:7.3f}  dgam {change['flight_path_angle_deg']:6.3f}  "
        f"dpsi {change['heading_deg']:6.3f} deg  {record['conic_status']}  "
        f"{1e3 * record['conic_solve_s']:6.1f} ms",
        file=sys.stderr,
        flush=True,
    )


def _attempt_lines(result: dict[str, Any]) -> list[str]:
    """Auto's attempts, one line each, the method kept and the cross-check's verdict."""
    attempts = result.get("attempts")
    if attempts is None:
        return []
    lines = [f"method: auto -> {result['method']}"]
    for a in attempts:
        value = "-" if a["objective"] is None else f"{a['objective']:.6g}"
        code = f" ({a['failure_code']})" if a["failure_code"] else ""
        kept = ", kept" if a["kept"] else ""
        lines.append(
            f"  attempt {a['attempt']} {a['method']} ({a['purpose']}): {a['status']}{code}, "
            f"{a['iterations']} iterations, {a['time_s']:.2f} s, objective {value}{kept}"
        )
    cross = result.get("cross_check") or {}
    if cross.get("warning"):
        lines.append(f"cross-check: {cross['warning']}")
    elif cross.get("agree"):
        lines.append(f"cross-check: the values agree ({100 * cross['relative_difference']:.3f} %)")
    elif cross.get("note"):
        lines.append(f"cross-check: {cross['note']}")
    return lines


def _summary(result: dict[str, Any]) -> str:
    """The result in a few lines: status, reason, auto's attempts, objective, verification,
    timing."""
    lines = [f"status: {result['status']}", *_attempt_lines(result)]
    if result.get("failure"):
        lines.append(f"reason: {result['failure']['code']}: {result['failure']['message']}")
        lines.extend(f"  try: {hint}" for hint in result["failure"].get("advice", []))
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


def _apply_overrides(raw: dict[str, Any], args: argparse.Namespace) -> None:
    """Put ``--method`` and ``--nodes`` into the document's method (a new method: defaults)."""
    if args.method or args.nodes is not None:
        method = raw.get("method")
        method = dict(method) if isinstance(method, dict) else {}
        if args.method and method.get("name") != args.method:
            method = {"name": args.method}
        if args.nodes is not None:
            method["nodes"] = args.nodes
        raw["method"] = method


CsvTable = Callable[[dict[str, Any]], str]
"""Turns a result document into the CSV text of its trajectory (given by the command line)."""


def _solve(args: argparse.Namespace, csv_table: CsvTable | None) -> int:
    """Check the output paths, load and validate the problem, solve, report; the exit code."""
    csv_path = getattr(args, "csv", None)
    for output in (args.output, csv_path):
        if output:
            check_output(output)
    raw = load_problem(args.problem)
    _apply_overrides(raw, args)

    from pydantic import ValidationError

    from app.schemas import ProblemDocument, issues_from_validation_error
    from worker.solver.methods import check_support

    try:
        doc = ProblemDocument.model_validate(raw)
    except ValidationError as exc:
        for line in issue_lines(
            f"invalid problem {args.problem}", issues_from_validation_error(exc)
        ):
            print(line, file=sys.stderr)
        return 2
    issues = check_support(doc)
    if issues:
        for line in issue_lines(f"method {doc.method.name} cannot solve this problem", issues):
            print(line, file=sys.stderr)
        return 2
    from app.schemas.plausibility import plausibility_warnings

    for warning in plausibility_warnings(doc):  # legal, but likely a slip of units
        print(f"warning: {warning.message}", file=sys.stderr)

    from worker.solver.api import solve_problem

    result = solve_problem(
        doc,
        on_iteration=None if args.quiet else _progress,
        on_kernels=functools.partial(_kernels_notice, quiet=args.quiet),
    )
    code = 0 if result["status"] == "succeeded" else 1
    print(_summary(result), flush=True)
    if args.output:
        write_result(args.output, result)
        print(f"result written to {args.output}", file=sys.stderr)
    if csv_path and csv_table is not None:
        if result.get("trajectory") is None:
            print(f"no trajectory: {csv_path} not written", file=sys.stderr)
            return code or 1
        write_text(csv_path, csv_table(result), "the trajectory")
        print(f"trajectory written to {csv_path}", file=sys.stderr)
    return code


def run(args: argparse.Namespace, csv_table: CsvTable | None = None) -> int:
    """Run the ``scenarios`` or ``solve`` subcommand; returns the exit code. ``csv_table``
    writes ``--csv`` (the command line passes it in: the CSV form is not the solver's)."""
    if args.command == "scenarios":
        for line in scenario_table(list_scenarios()):
            print(line)
        return 0
    try:
        return _solve(args, csv_table)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
