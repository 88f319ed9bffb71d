"""Score the methods on the user-problem suite against its NLP references.

    python -m bench.user_problems                          # auto and every method, every problem
    python -m bench.user_problems --methods auto --problems 001 004 --time-limit 60 --jobs out.json

Each referenced problem (``data/*.json``, written by ``bench.user_problems.reference``) is solved
through the library entry point the command line uses (``worker.solver.api.solve_problem``),
once with ``auto`` and once with each method whose own checks accept it, under a time limit, one
solve at a time, its CPU time measured. A solve succeeds when its status is ``succeeded``
(converged and verified) and its objective — the flown one where the result has it (the heat
load), else the optimized one — is within ``TOLERANCE`` (0.5 %) of the reference or better;
a ``succeeded`` result more than 0.5 % worse, or with a verified path maximum above its limit,
or on a problem the reference found infeasible, is a wrong success; a failed or timed-out solve
is an honest failure. The table gives, per method: the problems it accepts (feasible /
infeasible by the reference), the success rate on the feasible ones, wrong successes, honest
failures (on feasible / on infeasible problems, the latter also counted when their message names
a path limit, the final time, a zone or a terminal condition, and for the problems infeasible on
purpose whether it names the constraint the generator made binding), and the median
iterations, CPU seconds and their ratio to the NLP reference's CPU seconds (the best start's
meshes) on the same problems. ``--tabulate`` prints the table of earlier ``--jobs`` files.
"""

from __future__ import annotations

import argparse
import copy
import json
import re
import statistics
import sys
import time
from pathlib import Path
from typing import Any

from bench.user_problems.reference import DATA_DIR, infeasible_everywhere

TOLERANCE = 0.005
"""A success's objective is at most this much (relative) worse than the reference's."""
FLOORS = {"deg": 1.0, "s": 1.0, "m/s": 1.0, "J/m^2": 1.0}
"""Denominators' floors of the relative gap (a final latitude near 0 deg)."""
METHODS = ("auto", "energy-scp", "foh-ptr", "cheb-scvx", "hp-scp", "lgl-sqp")
LIMIT_RATIO = 1.01
"""A verified path maximum above this times its limit violates it (the verification's 1 %)."""
BINDING: dict[str, re.Pattern[str]] = {
    "heat_rate": re.compile(r"heat[- ]rate"),
    "dynamic_pressure": re.compile(r"dynamic[- ]pressure"),
    "load_factor": re.compile(r"load[- ]factor"),
    "zone": re.compile(r"\bzone"),
    "final_time": re.compile(r"final time"),
    "terminal": re.compile(r"\bterminal"),
}
"""What a failure's message may name as the binding constraint (a word match, case-folded)."""
PLANTED = {
    "heat_below_lift_up": "heat_rate",
    "terminal_dynamic_pressure": "dynamic_pressure",
    "downrange_beyond_speed": "final_time",
}
"""The constraint each infeasible-on-purpose argument of the generator makes binding."""


def load(selection: list[str] | None) -> list[dict[str, Any]]:
    """The referenced problems, those whose name starts with one of ``selection`` if given."""
    records = []
    for path in sorted(DATA_DIR.glob("*.json")):
        record = json.loads(path.read_text())
        if selection and not any(record["name"].startswith(s) for s in selection):
            continue
        records.append(record)
    return records


def reference_status(record: dict[str, Any]) -> str:
    """feasible (mesh-converged and its re-flight verified), infeasible (IPOPT declared every
    start infeasible), or unresolved (meshes did not agree, or the re-flight failed): not scored."""
    if record["status"] == "feasible":
        return "feasible" if record.get("reflight", {}).get("feasible") else "unresolved"
    if record["status"] == "infeasible" and not infeasible_everywhere(record["starts"]):
        return "unresolved"  # written before an iteration limit counted as no verdict
    return str(record["status"])


def minimized(objective: str, value: float) -> float:
    """The value as minimized: a max term negated."""
    return -value if objective.startswith("max") else value


def nlp_cpu(record: dict[str, Any]) -> float | None:
    """CPU seconds of the reference's best start over its meshes (None when infeasible)."""
    best = record.get("objective", {}).get("start")
    for start in record.get("starts", []):
        if start["start"] == best:
            return float(sum(m.get("cpu_s", 0.0) for m in start["meshes"]))
    return None


def accepted(document: dict[str, Any], method: str) -> bool:
    """Whether ``method`` (or auto, through any method) accepts the document."""
    from app.schemas import ProblemDocument
    from worker.solver.methods.selection import check_support

    return not check_support(ProblemDocument.model_validate(document))


def solve(document: dict[str, Any]) -> tuple[dict[str, Any], float]:
    """The result document and the CPU seconds of one solve."""
    from app.schemas import ProblemDocument
    from worker.solver.api import solve_problem

    cpu = time.process_time()
    result = solve_problem(ProblemDocument.model_validate(document))
    return result, time.process_time() - cpu


def iterations(result: dict[str, Any]) -> int:
    """SCP iterations of a result (all of auto's attempts)."""
    if result.get("attempts"):
        return int(sum(a.get("iterations") or 0 for a in result["attempts"]))
    return int((result.get("timing") or {}).get("iterations") or 0)


def judge(record: dict[str, Any], result: dict[str, Any]) -> dict[str, Any]:
    """Classify one solve against the reference: success, wrong success or honest failure."""
    status = result.get("status")
    verification = result.get("verification") or {}
    over = [
        name
        for name, entry in (verification.get("path_maxima") or {}).items()
        if entry.get("ratio") is not None and entry["ratio"] > LIMIT_RATIO
    ]
    out: dict[str, Any] = {"status": status, "violates": over}
    failure = result.get("failure") or {}
    out["failure"] = failure.get("code")
    out["message"] = failure.get("message")
    if status != "succeeded":
        out["verdict"] = "honest_failure"
        out.update(named_constraints(record, failure.get("message")))
        return out
    if reference_status(record) != "feasible":
        out["verdict"] = "wrong_success"
        out["why"] = "the reference found the problem infeasible"
        return out
    objective = record["objective"]["name"]
    entry = result.get("objective") or {}
    flown = entry.get("propagated_value")  # the flown value where the result has one
    value = float(flown if flown is not None else entry.get("value") or "nan")
    ref = float(record["objective"]["value"])
    unit = (result.get("objective") or {}).get("units", "")
    gap = (minimized(objective, value) - minimized(objective, ref)) / max(
        abs(ref), FLOORS.get(unit, 1e-9)
    )
    out["value"], out["reference"], out["gap"] = value, ref, gap
    if over or not verification.get("feasible", False):
        out["verdict"] = "wrong_success"
        out["why"] = f"violates {over}"
    elif gap > TOLERANCE:
        out["verdict"] = "wrong_success"
        out["why"] = f"{100 * gap:.2f} % worse than the reference"
    else:
        out["verdict"] = "success"
    return out


def _median(values: list[float]) -> str:
    return f"{statistics.median(values):.3g}" if values else "-"


def table(rows: list[dict[str, Any]], methods: list[str]) -> str:
    """The markdown table of the runs."""
    lines = [
        "| method | accepted (feasible / infeasible) | success rate | wrong successes "
        "| honest failures (feasible / infeasible, naming a constraint (the planted one of "
        "those infeasible on purpose; diverged)) | median iterations "
        "| median CPU s | median NLP CPU s | CPU / NLP |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for method in methods:
        mine = [r for r in rows if r["method"] == method]
        feasible = [r for r in mine if r["reference_status"] == "feasible"]
        infeasible = [r for r in mine if r["reference_status"] == "infeasible"]
        ok = [r for r in feasible if r["verdict"] == "success"]
        wrong = [r for r in mine if r["verdict"] == "wrong_success"]
        fail_f = [r for r in feasible if r["verdict"] == "honest_failure"]
        fail_i = [r for r in infeasible if r["verdict"] == "honest_failure"]
        named = [r for r in fail_i if r.get("names_constraint")]
        planted = [r for r in fail_i if "names_planted" in r]
        planted_ok = [r for r in planted if r["names_planted"]]
        diverged = [r for r in fail_i if r.get("failure") == "diverged"]
        rate = f"{len(ok)}/{len(feasible)}" + (
            f" ({100 * len(ok) / len(feasible):.0f} %)" if feasible else ""
        )
        ratios = [r["cpu_s"] / r["nlp_cpu_s"] for r in ok if r.get("nlp_cpu_s")]
        lines.append(
            f"| {method} | {len(feasible)} / {len(infeasible)} | {rate} | {len(wrong)} "
            f"| {len(fail_f)} / {len(fail_i)}, {len(named)} ({len(planted_ok)}/{len(planted)}"
            f" planted; {len(diverged)} diverged) | "
            f"{_median([r['iterations'] for r in mine])} | {_median([r['cpu_s'] for r in mine])} "
            f"| {_median([r['nlp_cpu_s'] for r in ok if r.get('nlp_cpu_s')])} "
            f"| {_median(ratios)} |"
        )
    return "\n".join(lines)


def parser() -> argparse.ArgumentParser:
    """main()'s argument parser, apart so a test checks the documented commands against it."""
    cli = argparse.ArgumentParser(prog="python -m bench.user_problems")
    cli.add_argument("--problems", nargs="*", help="name prefixes (e.g. 001 004)")
    cli.add_argument("--methods", nargs="*", default=list(METHODS), choices=METHODS)
    cli.add_argument("--time-limit", type=float, default=120.0, help="per solve, s")
    cli.add_argument("--jobs", type=Path, help="write every solve's verdict here (JSON)")
    cli.add_argument(
        "--tabulate",
        type=Path,
        nargs="+",
        metavar="JOBS",
        help="solve nothing: print the table of earlier --jobs files together (their failure "
        "messages judged again by today's rules)",
    )
    return cli


def named_constraints(record: dict[str, Any], message: str | None) -> dict[str, Any]:
    """What a failure's message names as binding, and whether it names the constraint the
    generator planted (infeasible-on-purpose problems only)."""
    text = (message or "").lower()
    out: dict[str, Any] = {"named": [n for n, pattern in BINDING.items() if pattern.search(text)]}
    out["names_constraint"] = bool(out["named"])
    planted = PLANTED.get(record["features"].get("infeasible_on_purpose") or "")
    if planted is not None:
        out["names_planted"] = planted in out["named"]
    return out


def tabulate(paths: list[Path], methods: list[str]) -> int:
    """Print the table of recorded rows (the last row of each problem and method wins)."""
    records = {r["name"]: r for r in load(None)}
    rows: dict[tuple[str, str], dict[str, Any]] = {}
    for path in paths:
        for row in json.loads(path.read_text()):
            if row["verdict"] == "honest_failure":
                row.update(named_constraints(records[row["problem"]], row.get("message")))
            rows[(row["problem"], row["method"])] = row
    kept = list(rows.values())
    infeasible = len({r["problem"] for r in kept if r["reference_status"] == "infeasible"})
    print(
        f"{len({r['problem'] for r in kept})} problems ({infeasible} infeasible by the reference)\n"
    )
    print(table(kept, [m for m in methods if any(r["method"] == m for r in kept)]))
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run the methods on the referenced problems and print the table."""
    args = parser().parse_args(argv)
    if args.tabulate:
        return tabulate(args.tabulate, args.methods)
    loaded = load(args.problems)
    records = [r for r in loaded if reference_status(r) in ("feasible", "infeasible")]
    rows: list[dict[str, Any]] = []
    for record in records:
        for method in args.methods:
            document = copy.deepcopy(record["problem"])
            document["method"] = {"name": method, "time_limit_s": args.time_limit}
            if method != "auto" and not accepted(document, method):
                continue  # auto runs on every problem: its refusal of a feasible one fails
            result, cpu = solve(document)
            row = {
                "problem": record["name"],
                "method": method,
                "reference_status": reference_status(record),
                "cpu_s": round(cpu, 3),
                "nlp_cpu_s": nlp_cpu(record),
                "iterations": iterations(result),
                # each run's method and value (auto's attempts, a named method's second start)
                "attempts": [[a["method"], a["objective"]] for a in result.get("attempts") or []],
                **judge(record, result),
            }
            rows.append(row)
            if args.jobs is not None:  # after every solve: a stopped run keeps what it did
                args.jobs.write_text(json.dumps(rows, indent=1) + "\n")
            print(
                f"{record['name']} {method}: {row['verdict']} {row['status']} "
                f"gap={row.get('gap')} cpu={cpu:.1f}s",
                file=sys.stderr,
                flush=True,
            )
    infeasible = sum(reference_status(r) == "infeasible" for r in records)
    print(
        f"{len(records)} problems ({infeasible} infeasible by the reference; "
        f"{len(loaded) - len(records)} unresolved, not scored), "
        f"time limit {args.time_limit:g} s per solve\n"
    )
    print(table(rows, args.methods))
    return 0


if __name__ == "__main__":
    sys.exit(main())
