"""Independent references of the user-problem suite: the NLP transcription, mesh-converged, from
several starts, its controls re-flown through the service's verification propagator.

For each problem and each start (``bench.nlp_collocation``: 0 the closest constant-bank flight,
1 the closest of the other bank sign), IPOPT solves on ``MESHES`` (40 then 80 intervals, the
finer warm-started from the coarser); when no start's two meshes agree to ``AGREEMENT`` (4
significant digits), the best start goes on to ``FINE_MESHES`` until two successive ones do. The
best agreeing start is the reference; its controls (bank and alpha or lambda, linear over each
interval as the transcription holds them) are flown by ``worker.solver.verification.verify`` and
the report's feasibility recorded. A problem where IPOPT converges from no start is marked
infeasible (``status: infeasible``), with the generator's physical argument when it made it so.

    python -m bench.user_problems.reference --count 90            # write data/ files
    python -m bench.user_problems.reference --indices 0 5 --force  # redo some

One process, one problem at a time (CPU heavy); a problem whose file exists is skipped, so a
stopped run resumes.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.user_problems.generate import SEED, generate

DATA_DIR = Path(__file__).resolve().parent / "data"
MESHES = (40, 80)
"""Intervals of the successive meshes of each start."""
FINE_MESHES = (160, 320)
"""Finer meshes the best start goes on to (warm-started) when its last two did not agree."""
REFLIGHT_MESHES = (160, 320)
"""Finer meshes the best start is refined on (warm-started) until its controls, re-flown open
loop, meet the verification: a long glide drifts from a coarse mesh's controls."""
AGREEMENT = 1e-4
"""Relative agreement of two meshes' objectives: 4 significant digits."""
STARTS = (0, 1)
INFEASIBLE = ("Infeasible_Problem_Detected",)
"""IPOPT's return status that declares a start infeasible."""
MAX_ITER = 1000


class QuadraticAttitude:
    """Bank and alpha (deg) or lambda between the NLP's points: per interval, the quadratic
    through its node, midpoint and node values (times nondimensional from the start)."""

    def __init__(self, t: np.ndarray, bank: np.ndarray, att: np.ndarray) -> None:
        self.t, self.bank, self.att = t, bank, att

    def _eval(self, values: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = (self.t.size - 1) // 2
        t0, t2 = self.t[0::2], self.t[2::2]
        k = np.clip(np.searchsorted(t0, s, side="right") - 1, 0, n - 1)
        h = t2[k] - t0[k]
        x = (s - t0[k]) / h  # 0..1 over the interval
        a, b, c = values[2 * k], values[2 * k + 1], values[2 * k + 2]
        # Lagrange basis on 0, 1/2, 1
        value = a * 2 * (x - 0.5) * (x - 1) - b * 4 * x * (x - 1) + c * 2 * x * (x - 0.5)
        slope = (a * (4 * x - 3) - b * (8 * x - 4) + c * (4 * x - 1)) / h
        return value, slope

    def at(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(bank in radians, alpha in degrees or lambda) at times ``s``."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        return self._eval(self.bank, s)[0], self._eval(self.att, s)[0]

    def rates_at(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(d bank/dt, d att/dt) per nondimensional time at ``s``."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        return self._eval(self.bank, s)[1], self._eval(self.att, s)[1]


def reflight(document: dict[str, Any], nlp: Any, arrays: dict[str, np.ndarray]) -> dict[str, Any]:
    """Fly the NLP's controls through the service's verification; the report's essentials."""
    from app.schemas import ProblemDocument
    from worker.solver.problem import build_problem
    from worker.solver.trajectory import OptimizedTrajectory
    from worker.solver.verification import verify

    problem = build_problem(ProblemDocument.model_validate(document))
    t, x, u = arrays["t"], arrays["x"], arrays["u"]
    bank = x[6] if nlp.bank_state else u[0]
    if nlp.has_att:
        raw = x[nlp.i_att_x] if nlp.att_state else u[1]
        att = raw if nlp.polar else np.degrees(raw)
    else:
        att = np.full(t.size, float("nan"))
    attitude = QuadraticAttitude(t, bank, att)
    traj = OptimizedTrajectory(
        grid_kind="time",
        grid=t,
        y=x[:6].T.copy(),
        t=t,
        bank=bank,
        alpha_deg=None,
        attitude=attitude,
    )
    report = verify(problem, traj)
    return {
        "feasible": report["feasible"],
        "reached_end": report["reached_end"],
        "terminal_error_vs_target": report["terminal_error_vs_target"],
        "path_maxima": {
            k: {kk: v[kk] for kk in ("max", "limit", "ratio", "within") if kk in v}
            for k, v in report["path_maxima"].items()
        },
        "no_fly_zones": [
            {"name": z["name"], "min_clearance_km": z["min_clearance_km"], "within": z["within"]}
            for z in report["no_fly_zones"]
        ],
        "control_limits": report["control_limits"],
        "heat_load_J_m2": report["heat_load_J_m2"],
        "final_state": report["final_state"],
    }


def _minimized(document: dict[str, Any], value: float) -> float:
    """The value as minimized (a single max term negated)."""
    objective = document["objective"]
    return -value if isinstance(objective, str) and objective.startswith("max") else value


def solve_start(document: dict[str, Any], start: int) -> dict[str, Any]:
    """One start through the meshes until two agree: each mesh's result and the last arrays."""
    from bench.nlp_collocation import EntryNlp

    meshes: list[dict[str, Any]] = []
    arrays = None
    nlp = None
    agreed = False
    for n in MESHES:
        cpu = time.process_time()
        try:
            nlp = EntryNlp(document, n, max_iter=MAX_ITER, start=start)
        except ValueError as error:
            meshes.append({"intervals": n, "status": f"no guess: {error}"})
            break
        if arrays is not None:
            nlp.warm_from(arrays)
        solution = nlp.solve()
        meshes.append(_mesh_record(n, solution, cpu))
        if not solution.converged:
            break
        arrays = solution.arrays
        if len(meshes) >= 2 and meshes[-2].get("objective") is not None:
            a, b = meshes[-2]["objective"], meshes[-1]["objective"]
            if abs(a - b) <= AGREEMENT * max(abs(b), 1e-9):
                agreed = True
                break
    return {"start": start, "meshes": meshes, "agreed": agreed, "_arrays": arrays, "_nlp": nlp}


def _mesh_record(n: int, solution: Any, cpu_start: float) -> dict[str, Any]:
    """What a reference keeps of one mesh's IPOPT solve (``cpu_start``: process time before)."""
    return {
        "intervals": n,
        "status": solution.status,
        "objective": solution.objective,
        "terms": solution.terms,
        "final_time_s": solution.final_time_s,
        "iterations": solution.iterations,
        "cpu_s": round(time.process_time() - cpu_start, 3),
    }


def ipopt_version() -> str:
    """The IPOPT CasADi ships (from its library's file name; CasADi does not report it)."""
    import casadi

    names = sorted(p.name for p in Path(casadi.__file__).parent.glob("libipopt.so.*.*"))
    return names[-1].removeprefix("libipopt.so.") if names else "unknown"


def refine(document: dict[str, Any], best: dict[str, Any], n: int) -> dict[str, Any]:
    """The best start solved again on ``n`` intervals, warm from its finest mesh so far."""
    from bench.nlp_collocation import EntryNlp

    cpu = time.process_time()
    nlp = EntryNlp(document, n, max_iter=MAX_ITER, start=best["start"])
    nlp.warm_from(best["_arrays"])
    solution = nlp.solve()
    mesh = _mesh_record(n, solution, cpu)
    if solution.converged:
        best["_arrays"] = solution.arrays
        best["_nlp"] = nlp
    return {"mesh": mesh, "converged": solution.converged, "nlp": nlp, "arrays": solution.arrays}


def infeasible_everywhere(starts: list[dict[str, Any]]) -> bool:
    """IPOPT declared every start infeasible (an iteration limit or a failed restoration is no
    verdict: such a problem stays unresolved)."""
    return all(s["meshes"] and s["meshes"][-1]["status"] in INFEASIBLE for s in starts)


def reference(entry: dict[str, Any]) -> dict[str, Any]:
    """The reference record of one generated problem."""
    import casadi

    document = entry["problem"]
    cpu = time.process_time()
    runs = [solve_start(document, s) for s in STARTS]
    finished = [
        r for r in runs if r["_arrays"] is not None and r["meshes"][-1]["intervals"] == MESHES[-1]
    ]
    if finished and not any(r["agreed"] for r in runs):  # the best start on finer meshes
        best = min(finished, key=lambda r: _minimized(document, r["meshes"][-1]["objective"]))
        for n in FINE_MESHES:
            finer = refine(document, best, n)
            best["meshes"].append(finer["mesh"])
            if not finer["converged"]:
                break
            a, b = best["meshes"][-2]["objective"], best["meshes"][-1]["objective"]
            if abs(a - b) <= AGREEMENT * max(abs(b), 1e-9):
                best["agreed"] = True
                break
    agreed = [r for r in runs if r["agreed"]]
    converged_any = any(m.get("status", "").startswith("Solve") for r in runs for m in r["meshes"])
    record: dict[str, Any] = {
        "name": entry["name"],
        "provenance": {
            "generator": "bench.user_problems.generate",
            "seed": entry["seed"],
            "index": entry["index"],
            "nlp": "bench.nlp_collocation (Hermite-Simpson, separated form, uniform time mesh)",
            "ipopt": {"tol": 1e-8, "max_iter": MAX_ITER},
            "meshes": list(MESHES),
            "fine_meshes": list(FINE_MESHES),
            "agreement_relative": AGREEMENT,
            "starts": list(STARTS),
            "casadi": str(getattr(casadi, "__version__", "unknown")),
            "ipopt_version": ipopt_version(),
            "python": platform.python_version(),
        },
        "features": entry["features"],
        "starts": [{k: v for k, v in r.items() if not k.startswith("_")} for r in runs],
    }
    if agreed:
        best = min(agreed, key=lambda r: _minimized(document, r["meshes"][-1]["objective"]))
        final = best["meshes"][-1]
        record["status"] = "feasible"
        record["objective"] = {
            "name": document["objective"],
            "value": final["objective"],
            "terms": final["terms"],
            "final_time_s": final["final_time_s"],
            "intervals": final["intervals"],
            "start": best["start"],
        }
        record["reflight"] = reflight(document, best["_nlp"], best["_arrays"])
        for n in REFLIGHT_MESHES:
            if record["reflight"]["feasible"] or n <= final["intervals"]:
                continue
            finer = refine(document, best, n)
            record["refinements"] = [*record.get("refinements", []), finer["mesh"]]
            if not finer["converged"]:
                break
            record["reflight"] = reflight(document, finer["nlp"], finer["arrays"])
            record["reflight"]["intervals"] = n
        record["reflight"].setdefault("intervals", final["intervals"])
        values = [_minimized(document, r["meshes"][-1]["objective"]) for r in finished]
        record["starts_spread_relative"] = (max(values) - min(values)) / max(abs(min(values)), 1e-9)
    elif not converged_any and infeasible_everywhere(record["starts"]):
        record["status"] = "infeasible"
        record["infeasibility_argument"] = entry["features"].get("infeasibility_argument")
    else:
        record["status"] = "unresolved"  # converged somewhere but no two meshes agreed
    record["cpu_s"] = round(time.process_time() - cpu, 2)
    return record


def path_of(name: str) -> Path:
    """The data file of a problem."""
    return DATA_DIR / f"{name}.json"


def parser() -> argparse.ArgumentParser:
    """main()'s argument parser, apart so a test checks the documented commands against it."""
    cli = argparse.ArgumentParser(prog="python -m bench.user_problems.reference")
    cli.add_argument("--count", type=int, default=90, help="problems 0..count-1")
    cli.add_argument("--indices", type=int, nargs="*", help="only these indices")
    cli.add_argument("--seed", type=int, default=SEED)
    cli.add_argument("--force", action="store_true", help="redo existing files")
    return cli


def main(argv: list[str] | None = None) -> int:
    """Generate and reference problems; write one JSON file each (problem + reference)."""
    args = parser().parse_args(argv)
    DATA_DIR.mkdir(parents=True, exist_ok=True)
    indices = args.indices if args.indices else list(range(args.count))
    for index in indices:
        entry = generate(index, args.seed)
        out = path_of(entry["name"])
        if out.exists() and not args.force:
            continue
        record = reference(entry)
        record["problem"] = entry["problem"]
        out.write_text(json.dumps(record, indent=1, default=_plain) + "\n")
        objective = record.get("objective", {}).get("value", math.nan)
        feasible = record.get("reflight", {}).get("feasible")
        print(
            f"{entry['name']}: {record['status']} {objective:.6g} reflight={feasible} "
            f"cpu={record['cpu_s']:.1f}s",
            flush=True,
        )
    return 0


def _plain(value: Any) -> Any:
    """numpy scalars and arrays as JSON values."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(type(value).__name__)


if __name__ == "__main__":
    sys.exit(main())
