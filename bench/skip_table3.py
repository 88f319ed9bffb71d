"""Paper 004's Table 3 repeated on this machine: its method (``lgl-sqp``: a GA or PSO global
initial guess, then LGL collocation solved by SQP) on the paper's skip entry with thrust
(``shuttle-skip-min-propellant``: two linked phases, minimum propellant), beside a general NLP
solver on the same problem, in one run.

One row per run of the method, for each algorithm (ga, pso) and seed, every other option at its
default: status (and failure code), the propellant burnt (kg) and its difference from the
independent reference (9085.75 kg), the time of the global search (the sum of the wall times of
its generations, the history's ``global_guess`` records), the time of the SQP (the sum of its
iterations' wall times, the ``sqp`` records) and its iterations, the verification time, whether
the propagated controls were found feasible, and the largest misses of the propagated phase
ends in altitude (m) and flight-path angle (deg). Then, per algorithm, the shape of Table 3:
the runs that succeeded within 0.5 % of the reference and the median times to run the GA / PSO
trajectory and to run the SQP. Last, the NLP (``bench.nlp_skip``: Hermite–Simpson collocation
of both phases, IPOPT through CasADi, its own equations in CasADi symbols) at the given
intervals per phase: IPOPT's status, iterations, solve time (IPOPT alone, the NLP built) and
propellant.

    pip install -e '.[bench]'   # CasADi
    python -m bench.skip_table3 [--seeds 1 2 3 4 5] [--algorithms ga pso]
        [--nlp-intervals 150 50] [--json PATH]

The timings are wall times on whatever machine runs this; on a shared 2-core machine they are
noisy from run to run, so read them as ratios within one run (guess against SQP, GA against
PSO, the method against IPOPT), not as absolute figures.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import statistics
import time
from pathlib import Path
from typing import Any

from app.schemas import ProblemDocument
from worker.solver.api import solve_problem
from worker.solver.scenarios import get_scenario

SCENARIO = "shuttle-skip-min-propellant"
REFERENCE_KG = 9085.75
"""The scenario's independent reference (CasADi + IPOPT, 800 + 320 Hermite–Simpson intervals)."""
BAND_PERCENT = 0.5
"""A run counts in the summary when it succeeded within this much of the reference."""
DEFAULT_SEEDS = (1, 2, 3, 4, 5)
ALGORITHMS = ("ga", "pso")


def _stage_walls(history: list[dict[str, Any]], stage: str) -> list[float]:
    """The wall times of the history's records of ``stage``."""
    return [
        float(record.get("iteration_wall_s") or 0.0)
        for record in history
        if (record.get("extra") or {}).get("stage") == stage
    ]


def _end_misses(verification: dict[str, Any]) -> dict[str, float | None]:
    """The largest |miss| of the propagated phase ends, over the phases, per end condition."""
    out: dict[str, float | None] = {"altitude_m": None, "flight_path_angle_deg": None}
    for phase in verification.get("phases") or []:
        for name in out:
            entry = (phase.get("end_error_vs_target") or {}).get(name)
            if entry is None:
                continue
            miss = abs(float(entry["error"]))
            current = out[name]
            out[name] = miss if current is None else max(current, miss)
    return out


def method_row(algorithm: str, seed: int) -> dict[str, Any]:
    """One solve of the scenario by ``lgl-sqp`` with the given global search and seed."""
    document = copy.deepcopy(get_scenario(SCENARIO).problem)
    document["method"] = {
        "name": "lgl-sqp",
        "global_guess": {"algorithm": algorithm, "seed": seed},
    }
    start = time.perf_counter()
    result = solve_problem(ProblemDocument.model_validate(document))
    total = time.perf_counter() - start
    history = result.get("history") or []
    guess = _stage_walls(history, "global_guess")
    sqp = _stage_walls(history, "sqp")
    verification = result.get("verification") or {}
    timing = result.get("timing") or {}
    value = (result.get("objective") or {}).get("value")
    propellant = float(value) if value is not None else None
    misses = _end_misses(verification)
    return {
        "label": f"lgl-sqp, {algorithm}, seed {seed}",
        "algorithm": algorithm,
        "seed": seed,
        "status": result["status"],
        "failure": (result.get("failure") or {}).get("code"),
        "propellant_kg": propellant,
        "off_percent": (None if propellant is None else 100.0 * (propellant / REFERENCE_KG - 1.0)),
        "guess_s": sum(guess),
        "generations": len(guess),
        "sqp_s": sum(sqp),
        "sqp_iterations": len(sqp),
        "optimization_s": timing.get("wall_s"),
        "verification_s": timing.get("verification_s"),
        "total_s": total,
        "feasible": bool(verification.get("feasible")) if verification else None,
        "altitude_miss_m": misses["altitude_m"],
        "flight_path_angle_miss_deg": misses["flight_path_angle_deg"],
    }


def within_band(row: dict[str, Any]) -> bool:
    """Whether a run succeeded within ``BAND_PERCENT`` of the reference."""
    off = row.get("off_percent")
    return row["status"] == "succeeded" and off is not None and abs(off) <= BAND_PERCENT


def summary(rows: list[dict[str, Any]], algorithm: str) -> dict[str, Any]:
    """Table 3's line of one algorithm: runs within the band and median times (all runs, and
    the SQP over the runs within the band)."""
    mine = [r for r in rows if r["algorithm"] == algorithm]
    good = [r for r in mine if within_band(r)]

    def median(values: list[float]) -> float | None:
        return statistics.median(values) if values else None

    return {
        "algorithm": algorithm,
        "runs": len(mine),
        "within_band": len(good),
        "median_guess_s": median([r["guess_s"] for r in mine]),
        "median_sqp_s": median([r["sqp_s"] for r in mine]),
        "median_sqp_s_within_band": median([r["sqp_s"] for r in good]),
        "median_sqp_iterations": median([float(r["sqp_iterations"]) for r in mine]),
    }


def nlp_row(intervals: list[int]) -> dict[str, Any]:
    """One IPOPT solve of the NLP (its solve time; the build is timed apart)."""
    from bench.nlp_skip import SkipNlp

    document = copy.deepcopy(get_scenario(SCENARIO).problem)
    start = time.perf_counter()
    nlp = SkipNlp(document, intervals)
    build = time.perf_counter() - start
    solution = nlp.solve()
    propellant = solution.propellant_kg
    finite = math.isfinite(propellant)
    return {
        "label": "NLP, Hermite-Simpson, " + " + ".join(str(n) for n in intervals) + " intervals",
        "intervals": intervals,
        "status": solution.status,
        "success": solution.success,
        "iterations": solution.iterations,
        "solve_s": solution.solve_s,
        "build_s": build,
        "propellant_kg": propellant if finite else None,
        "off_percent": 100.0 * (propellant / REFERENCE_KG - 1.0) if finite else None,
        "durations_s": solution.durations_s,
    }


def cell(value: Any, fmt: str = "{:.3g}") -> str:
    """A table cell: ``fmt`` for a float, a dash when absent, yes/no for a flag."""
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return fmt.format(value)
    return str(value)


def runs_table(rows: list[dict[str, Any]]) -> str:
    """The method's runs as a Markdown table."""
    lines = [
        "| run | status | propellant kg | vs 9085.75 kg | guess s | SQP s | SQP iterations "
        "| verification s | feasible | altitude miss m | FPA miss deg |",
        "|" + "---|" * 11,
    ]
    for r in rows:
        status = r["status"] + (f" ({r['failure']})" if r["failure"] else "")
        lines.append(
            f"| {r['label']} | {status} | {cell(r['propellant_kg'], '{:.2f}')} | "
            f"{cell(r['off_percent'], '{:+.3f} %')} | {cell(r['guess_s'], '{:.1f}')} | "
            f"{cell(r['sqp_s'], '{:.1f}')} | {r['sqp_iterations']} | "
            f"{cell(r['verification_s'], '{:.2f}')} | {cell(r['feasible'])} | "
            f"{cell(r['altitude_miss_m'], '{:.3g}')} | "
            f"{cell(r['flight_path_angle_miss_deg'], '{:.3g}')} |"
        )
    return "\n".join(lines)


def summary_table(lines_in: list[dict[str, Any]], nlp: dict[str, Any] | None) -> str:
    """Table 3's shape: per algorithm, runs within the band and median times; the NLP below."""
    lines = [
        f"| algorithm | succeeded within {BAND_PERCENT:g} % | time to run GA / PSO trajectory s "
        "(median) | time to run SQP s (median, all / within band) | SQP iterations (median) |",
        "|---|---|---|---|---|",
    ]
    for s in lines_in:
        lines.append(
            f"| {s['algorithm']} | {s['within_band']}/{s['runs']} | "
            f"{cell(s['median_guess_s'], '{:.1f}')} | {cell(s['median_sqp_s'], '{:.1f}')} / "
            f"{cell(s['median_sqp_s_within_band'], '{:.1f}')} | "
            f"{cell(s['median_sqp_iterations'], '{:g}')} |"
        )
    if nlp is not None:
        lines += [
            "",
            "| NLP | IPOPT status | iterations | IPOPT solve s | build s | propellant kg "
            "| vs 9085.75 kg |",
            "|---|---|---|---|---|---|---|",
            f"| {nlp['label']} | {nlp['status']} | {nlp['iterations']} | "
            f"{cell(nlp['solve_s'], '{:.2f}')} | {cell(nlp['build_s'], '{:.2f}')} | "
            f"{cell(nlp['propellant_kg'], '{:.3f}')} | {cell(nlp['off_percent'], '{:+.4f} %')} |",
        ]
    return "\n".join(lines)


def parser() -> argparse.ArgumentParser:
    """main()'s argument parser, apart so a test checks the documented commands against it."""
    cli = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cli.add_argument("--seeds", type=int, nargs="+", default=list(DEFAULT_SEEDS))
    cli.add_argument("--algorithms", nargs="+", choices=ALGORITHMS, default=list(ALGORITHMS))
    cli.add_argument(
        "--nlp-intervals",
        type=int,
        nargs="*",
        default=[150, 50],
        metavar="N",
        help="NLP intervals per phase (none: no NLP run)",
    )
    cli.add_argument("--json", type=Path, default=None, metavar="PATH", help="write the rows")
    return cli


def main() -> None:
    args = parser().parse_args()
    rows = []
    for algorithm in args.algorithms:
        for seed in args.seeds:
            row = method_row(algorithm, seed)
            rows.append(row)
            print(
                f"{row['label']}: {row['status']}, {cell(row['propellant_kg'], '{:.2f}')} kg, "
                f"guess {row['guess_s']:.1f} s, SQP {row['sqp_s']:.1f} s "
                f"({row['sqp_iterations']} iterations)",
                flush=True,
            )
    nlp = nlp_row(args.nlp_intervals) if args.nlp_intervals else None
    lines = [summary(rows, a) for a in args.algorithms]
    print()
    print(runs_table(rows))
    print()
    print(summary_table(lines, nlp))
    if args.json is not None:
        payload = {
            "scenario": SCENARIO,
            "reference_kg": REFERENCE_KG,
            "runs": rows,
            "summary": lines,
            "nlp": nlp,
        }
        args.json.write_text(json.dumps(payload, indent=2) + "\n")


if __name__ == "__main__":
    main()
