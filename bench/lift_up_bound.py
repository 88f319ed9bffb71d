"""Is the least-bank flight's first pull-up a bound no bank profile can beat? Measured by NLP.

The pre-check ``worker.solver.prechecks`` refuses a problem whose path limit lies below the peak
that the least-bank flight (bank 0, the angle of attack on its schedule) reaches in its first
pull-up. That is sound only if no other bank profile flies from the entry point to the terminal
altitude with a lower peak. This benchmark asks an independent NLP (``bench.nlp_collocation``:
Hermite–Simpson collocation, IPOPT) for the least peak over every bank profile: minimize z
subject to quantity <= z at every node and midpoint, from the entry state to the problem's
terminal altitude, free final time, |bank| <= bank_max and no other condition (a relaxation of
every problem with that entry point). Each NLP answer's bank profile is then flown through the
solver's dynamics (its peak between the collocation points included), from two starts.

    python -m bench.lift_up_bound [--intervals 150] [--only CASE ...]

Output: per case and quantity, the pre-check's peak, the NLP's least peak on its points, the
flown peak of the NLP's bank profile, and their ratios to the pre-check's.
"""

from __future__ import annotations

import argparse
import copy
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from app.schemas import ProblemDocument
from bench.nlp_collocation import EntryNlp
from worker.solver.models.scalar_rates import time_rates
from worker.solver.path_limits import path_values
from worker.solver.prechecks.pull_up import least_bank_pull_up
from worker.solver.problem import EntryProblem, build_problem
from worker.solver.scenarios import get_scenario

SCALE = {"heat_rate_W_m2": 1e6, "dynamic_pressure_Pa": 1e4, "load_factor_g": 1.0}
NLP_NAME = {
    "heat_rate_W_m2": "heat_rate",
    "dynamic_pressure_Pa": "dynamic_pressure",
    "load_factor_g": "load_factor",
}
START_BANKS_DEG = (None, 45.0)
"""The NLP's starts: its own constant-bank guess, and the same states with the bank at 45 deg."""


def _set(doc: dict[str, Any], **changes: Any) -> dict[str, Any]:
    out = copy.deepcopy(doc)
    for path, value in changes.items():
        node = out
        keys = path.split("__")
        for key in keys[:-1]:
            node = node[key]
        node[keys[-1]] = value
    return out


def _user_problem() -> dict[str, Any]:
    """Paper 002's vehicle from a moved entry point to a target of a user's own."""
    doc = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    doc["initial_state"].update(
        longitude_deg=10, latitude_deg=5, altitude_m=95000, velocity_m_s=7300, heading_deg=20
    )
    doc["terminal"] = {"altitude_m": 25000, "longitude_deg": 30, "latitude_deg": 55}
    return doc


def cases() -> dict[str, dict[str, Any]]:
    """The problems measured (exponential atmospheres: the NLP's models)."""
    p000 = get_scenario("rlv-min-heat-load").problem
    p002 = get_scenario("rlv-max-terminal-velocity").problem
    return {
        "000": copy.deepcopy(p000),
        "000 120 km, -1.5 deg": _set(
            p000, initial_state__altitude_m=120000, initial_state__flight_path_angle_deg=-1.5
        ),
        "000 mass x1.5": _set(p000, vehicle__mass_kg=157500),
        "002": copy.deepcopy(p002),
        "002 westward": _set(p002, initial_state__heading_deg=270),
        "002 -2 deg": _set(p002, initial_state__flight_path_angle_deg=-2),
        "002 6 800 m/s": _set(p002, initial_state__velocity_m_s=6800),
        "user": _user_problem(),
    }


def relaxed(doc: dict[str, Any]) -> dict[str, Any]:
    """Every flight from ``doc``'s entry point to its terminal altitude: free final time, only
    the bank bound kept, no path limit (the heat-rate model kept for its value)."""
    out = copy.deepcopy(doc)
    altitude = out["terminal"]["altitude_m"]
    altitude = altitude if isinstance(altitude, int | float) else altitude["value"]
    out["terminal"] = {"altitude_m": altitude}
    out["final_time"] = {"kind": "free"}
    out["objective"] = "max_terminal_velocity"  # replaced below
    heat = out["path_constraints"]["heat_rate"]
    out["path_constraints"] = {"heat_rate": {"k_q": heat["k_q"], "max_W_m2": 1e12}}
    out["control_limits"] = {"bank_max_deg": out["control_limits"].get("bank_max_deg", 80.0)}
    out.pop("energy", None)
    return out


def _flown_peaks(model: EntryProblem, t_s: np.ndarray, bank: np.ndarray) -> dict[str, float]:
    """Fly the bank profile (linear in time between the NLP's points) and read its peaks."""
    forces, omega, ts = model.forces, model.omega, model.scales.time_s
    t_nd = t_s / ts

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        sigma = float(np.interp(t, t_nd, bank))
        _, lift, drag, _ = forces.lift_drag(y[0], y[3])
        return time_rates(y, math.cos(sigma), math.sin(sigma), float(lift), float(drag), omega)

    solution = solve_ivp(
        rhs, (0.0, float(t_nd[-1])), model.y0, method="DOP853", rtol=1e-9, atol=1e-11,
        dense_output=True, max_step=0.5 / ts,
    )  # fmt: skip
    t = np.linspace(0.0, float(solution.t[-1]), int(t_s[-1] / 0.25) + 1)
    y = solution.sol(t)
    values = path_values(forces, model.heat_model, y[0], y[3], forces.terms(y[0], y[3]))
    return {
        "heat_rate_W_m2": float(np.max(values.heat_rate)),
        "dynamic_pressure_Pa": float(np.max(values.dynamic_pressure)),
        "load_factor_g": float(np.max(values.load_factor)),
    }


def least_peak(
    doc: dict[str, Any], quantity: str, intervals: int, start_bank_deg: float | None
) -> tuple[str, float, float]:
    """The NLP's least peak of ``quantity`` over flights to the terminal altitude: IPOPT's
    status, the value on its points and the flown peak of its bank profile."""
    nlp = EntryNlp(relaxed(doc), intervals, max_iter=3000)
    opti = nlp.opti
    z = opti.variable()
    scale = SCALE[quantity]
    for cols in (nlp.X, nlp.Xm):
        for k in range(cols.shape[1]):
            opti.subject_to(nlp._path(cols[:, k])[NLP_NAME[quantity]] / scale <= z)
    opti.minimize(z)
    opti.set_initial(z, 3.0)
    if start_bank_deg is not None:
        opti.set_initial(nlp.U, math.radians(start_bank_deg))
        opti.set_initial(nlp.Um, math.radians(start_bank_deg))
    try:
        sol = opti.solve()
    except RuntimeError:
        return str(opti.stats()["return_status"]), math.nan, math.nan
    tf = float(sol.value(nlp.tf)) * nlp.t_unit
    nodes = np.linspace(0.0, tf, intervals + 1)
    mids = 0.5 * (nodes[:-1] + nodes[1:])
    t = np.empty(2 * intervals + 1)
    t[0::2], t[1::2] = nodes, mids
    bank = np.empty_like(t)
    bank[0::2] = np.atleast_2d(sol.value(nlp.U))[0]
    bank[1::2] = np.atleast_2d(sol.value(nlp.Um))[0]
    model = build_problem(ProblemDocument.model_validate(doc))
    flown = _flown_peaks(model, t, bank)[quantity]
    return str(sol.stats()["return_status"]), float(sol.value(z)) * scale, flown


def main(argv: list[str] | None = None, out: Callable[[str], None] = print) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--intervals", type=int, default=150)
    parser.add_argument("--only", nargs="*", default=None)
    parser.add_argument("--quantities", nargs="*", default=["heat_rate_W_m2"], choices=list(SCALE))
    args = parser.parse_args(argv)
    out(
        f"{'case':22} {'quantity':20} {'pre-check':>11} {'NLP points':>11} {'NLP flown':>11} "
        f"{'flown/pre':>9}  starts"
    )
    for name, doc in cases().items():
        if args.only and name not in args.only:
            continue
        model = build_problem(ProblemDocument.model_validate(doc))
        pull_up = least_bank_pull_up(model)
        for quantity in args.quantities:
            bound = pull_up.peaks[quantity].value
            runs = [least_peak(doc, quantity, args.intervals, b) for b in START_BANKS_DEG]
            ok = [r for r in runs if math.isfinite(r[2])]
            best = min(ok, key=lambda r: r[2]) if ok else ("failed", math.nan, math.nan)
            statuses = ",".join(r[0].replace("Solve_Succeeded", "ok") for r in runs)
            out(
                f"{name:22} {quantity:20} {bound:11.6g} {best[1]:11.6g} {best[2]:11.6g} "
                f"{best[2] / bound:9.5f}  {statuses}"
            )


if __name__ == "__main__":
    main()
