"""Verification of a flight in phases (paper 004): the method's controls flown through the full
powered dynamics, phase after phase.

The same propagation and checks as ``verification`` for one phase, with what phases add: each
phase is integrated (scipy DOP853, the same tolerances) from the state the previous one ended
in (the phases are linked by state continuity) under that phase's controls as the method
represents them (``PhaseControls.at``), restarting wherever the control's pieces meet
(``PhaseControls.breaks``); only the ground ends a phase early. Each phase's end is checked
against its own end conditions, its flight against its own path limits and control bounds; the
report adds one entry per phase (``phases``) and otherwise reads as the single-phase report:
the last phase's end is the terminal check, a path peak names the phase whose limit binds.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from worker.solver.constraints.no_fly import zone_distance
from worker.solver.models.powered import PoweredPathValues, powered_path_values
from worker.solver.path_limits import HeatRateModel
from worker.solver.phased_problem import PhasedProblem, PhaseModel
from worker.solver.problem import TerminalTarget
from worker.solver.trajectory import TIME_STATE_NAMES, Array, PhasedTrajectory
from worker.solver.units import COLUMN_UNITS
from worker.solver.verification import (
    ATOL,
    RTOL,
    Propagation,
    StopCheck,
    VerificationTolerances,
    poller,
    propagate_in_pieces,
    sample_rows,
    terminal_error,
    to_si,
    waypoint_passes,
)

PATH_KEYS = ("heat_rate_W_m2", "dynamic_pressure_Pa", "load_factor_g")
"""The path quantities, as the report and the columns name them."""


@dataclass
class PhaseFlight:
    """One phase's propagation: the integrator's solution of each segment between restarts."""

    index: int
    start: float  # nondimensional time from the flight's start
    x_start: Array  # the state the phase starts in (the previous phase's end)
    segments: list[Any]
    reached_end: bool  # False: the ground (or an integrator failure) ended it early

    @property
    def end(self) -> float:
        """Where the propagation of the phase ended (its end time unless it ended early)."""
        return float(self.segments[-1].t[-1]) if self.segments else self.start

    @property
    def x_end(self) -> Array:
        return np.asarray(self.segments[-1].y[:, -1]) if self.segments else self.x_start

    @property
    def steps(self) -> int:
        return Propagation(self.segments, 0, 1).steps if self.segments else 0

    def sol(self, t: Array) -> Array:
        """States (len(t), n_states) at times ``t`` within the phase, from the dense outputs."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if not self.segments:  # a phase of no duration
            return np.tile(self.x_start, (t.size, 1))
        return Propagation(self.segments, 0, 1).sol(t).T


def propagate_phased(
    problem: PhasedProblem,
    traj: PhasedTrajectory,
    *,
    rtol: float = RTOL,
    atol: float = ATOL,
    should_stop: StopCheck | None = None,
) -> list[PhaseFlight]:
    """Integrate the powered dynamics phase after phase from ``problem.x0`` under the method's
    controls, restarting at each phase's control breaks; the state carries over from one phase
    into the next. A ground impact ends the flight (the phases after it are not flown).
    ``should_stop`` is asked as in ``verification.propagate``."""
    poll = poller(should_stop)
    model = problem.model
    controls = traj.controls

    def ground(t: float, x: Array) -> float:
        return float(x[0] - 1.0)

    ground.terminal = True  # type: ignore[attr-defined]
    flights: list[PhaseFlight] = []
    x = np.asarray(problem.x0, dtype=float)
    for p in range(len(problem.phases)):
        start, end = (float(b) for b in traj.bounds[p])
        at = np.zeros(1)

        def rhs(t: float, y: Array, p: int = p, at: Array = at) -> Array:
            poll()
            at[0] = t
            u = np.asarray(controls.at(p, at), dtype=float).reshape(1, -1)
            rates: Array = model.rates(y[None, :], u)[0]
            return rates

        breaks = np.asarray(controls.breaks(p), dtype=float)
        stops = [float(b) for b in np.unique(breaks) if start < b < end] + [end]
        segments, status = propagate_in_pieces(rhs, start, x, stops, rtol, atol, [ground])
        flight = PhaseFlight(
            index=p, start=start, x_start=x, segments=segments, reached_end=status == 0
        )
        x = segments[-1].y[:, -1] if segments else x
        flights.append(flight)
        if not flight.reached_end:
            break
    return flights


def flight_heat_model(problem: PhasedProblem) -> HeatRateModel | None:
    """The vehicle's heat-rate model: the problem's, else the first phase's that has one."""
    if problem.base.heat_model is not None:
        return problem.base.heat_model
    return next((ph.limits.heat for ph in problem.phases if ph.limits.heat is not None), None)


def phase_path_values(
    problem: PhasedProblem, phase: PhaseModel, x: Array, u: Array
) -> PoweredPathValues:
    """Heat rate, dynamic pressure and load factor at rows of ``phase``'s flight: its own heat
    model, else the flight's (a phase without a heat limit still heats)."""
    limits = phase.limits
    if limits.heat is None:
        limits = dataclasses.replace(limits, heat=flight_heat_model(problem))
    return powered_path_values(problem.model, limits, x, u)


def path_limit(phase: PhaseModel, key: str) -> float | None:
    """``phase``'s limit on path quantity ``key`` (SI), None when it has none."""
    lim = phase.limits
    if key == "heat_rate_W_m2":
        return lim.heat_max_W_m2 if lim.heat is not None else None
    if key == "dynamic_pressure_Pa":
        return lim.dynamic_pressure_max_Pa
    return lim.load_factor_max_g


def path_columns(pv: PoweredPathValues) -> dict[str, Array]:
    """The path values by their column names."""
    return {
        "heat_rate_W_m2": pv.heat_rate,
        "dynamic_pressure_Pa": pv.dynamic_pressure,
        "load_factor_g": pv.load_factor,
    }


def state_si(problem: PhasedProblem, x: Array) -> dict[str, float]:
    """One powered state in the API's units: the point-mass states, the mass (kg) and, when
    the thrust lags its command, the thrust (N)."""
    out = to_si(problem.base, x[:6])
    if problem.model.thruster is not None:
        out["mass_kg"] = float(x[6] * problem.mass_kg)
        if problem.model.thruster.lagged:
            out["thrust_n"] = float(x[7] * problem.thrust_unit_n)
    return out


def end_checks(
    end_si: dict[str, TerminalTarget], final_si: dict[str, float], tol: VerificationTolerances
) -> tuple[dict[str, Any], bool]:
    """Each end condition's miss (soft ones reported, fixed and range ones decide) and whether
    every fixed and range condition is met within its tolerance."""
    checks: dict[str, Any] = {}
    hard_ok = True
    for name in TIME_STATE_NAMES:
        spec = end_si[name]
        if spec.kind == "free":
            continue
        err = terminal_error(spec, final_si[name])
        tolerance = getattr(tol, name)
        within = abs(err) <= tolerance
        if spec.kind in ("fixed", "range"):
            hard_ok &= within
        checks[name] = {"kind": spec.kind, "error": err, "tolerance": tolerance, "within": within}
    return checks, hard_ok


@dataclass
class PhaseSamples:
    """A phase's flight on the dense grid the checks read: times, states, controls, path values."""

    phase: int
    t: Array
    x: Array
    u: Array
    path: dict[str, Array]


def _samples(
    problem: PhasedProblem, traj: PhasedTrajectory, flight: PhaseFlight, per_interval: int
) -> PhaseSamples:
    """``per_interval`` samples between consecutive node times of the flown part of a phase."""
    p = flight.index
    nodes = traj.t[traj.phase == p]
    ends = np.concatenate([[flight.start], nodes, [flight.end]])
    t_nodes = np.unique(np.clip(ends, flight.start, flight.end))
    pieces = [np.linspace(a, b, per_interval + 1) for a, b in itertools.pairwise(t_nodes)]
    t_fine = np.unique(np.concatenate(pieces)) if pieces else t_nodes
    x = flight.sol(t_fine)
    u = np.asarray(traj.controls.at(p, t_fine), dtype=float).reshape(t_fine.size, -1)
    pv = phase_path_values(problem, problem.phases[p], x, u)
    return PhaseSamples(phase=p, t=t_fine, x=x, u=u, path=path_columns(pv))


def _deviation(
    problem: PhasedProblem, traj: PhasedTrajectory, flights: list[PhaseFlight]
) -> dict[str, float]:
    """Largest |propagated - optimized| state at the nodes of the flown phases (SI)."""
    sc = problem.base.scales
    n = problem.model.n_states
    worst = np.zeros(n)
    for flight in flights:
        mask = traj.phase == flight.index
        if not np.any(mask):
            continue
        t_nodes = np.clip(traj.t[mask], flight.start, flight.end)
        dev = np.abs(flight.sol(t_nodes) - traj.x[mask][:, :n])
        worst = np.maximum(worst, np.max(dev, axis=0))
    out = {
        "altitude_m": float(worst[0] * sc.radius_m),
        "longitude_deg": math.degrees(worst[1]),
        "latitude_deg": math.degrees(worst[2]),
        "velocity_m_s": float(worst[3] * sc.speed_m_s),
        "flight_path_angle_deg": math.degrees(worst[4]),
        "heading_deg": math.degrees(worst[5]),
    }
    if n > 6:
        out["mass_kg"] = float(worst[6] * problem.mass_kg)
    if n > 7:
        out["thrust_n"] = float(worst[7] * problem.thrust_unit_n)
    return out


def _path_maxima(
    problem: PhasedProblem, samples: list[PhaseSamples], tol: VerificationTolerances
) -> tuple[dict[str, Any], bool]:
    """Each path quantity's peak over the whole flight, with the limit, ratio and verdict of
    the phase whose value / limit is largest (each phase has its own limits)."""
    ts, t0 = problem.base.scales.time_s, problem.base.t0
    has_heat = flight_heat_model(problem) is not None
    out: dict[str, Any] = {}
    ok = True
    for key in PATH_KEYS:
        if key == "heat_rate_W_m2" and not has_heat:
            continue
        values = np.concatenate([s.path[key] for s in samples])
        times = np.concatenate([s.t for s in samples])
        at = int(np.argmax(values))
        entry: dict[str, Any] = {"max": float(values[at]), "at_time_s": float(times[at] * ts + t0)}
        binding: tuple[float, float, str] | None = None  # (ratio, limit, phase name)
        for s in samples:
            phase = problem.phases[s.phase]
            limit = path_limit(phase, key)
            if limit is None or s.t.size == 0:
                continue
            ratio = float(np.max(s.path[key])) / limit
            if binding is None or ratio > binding[0]:
                binding = (ratio, limit, phase.name)
        if binding is not None:
            ratio, limit, name = binding
            entry["limit"] = limit
            entry["ratio"] = ratio
            entry["within"] = ratio <= 1.0 + tol.path_limit_relative
            entry["phase"] = name
            ok &= entry["within"]
        out[key] = entry
    return out, ok


def _control_peaks(
    problem: PhasedProblem, samples: list[PhaseSamples], tol: VerificationTolerances
) -> tuple[dict[str, Any], bool]:
    """The flown angle of attack and bank on the dense grid against each phase's bounds, as
    ``verification._control_peaks`` reads them: each ratio the share of the range's half-width
    used from its middle (|bank| / limit for symmetric bank ranges in every phase), the peak
    the largest share over all phases, with that phase's bound as the limit."""
    ts, t0 = problem.base.scales.time_s, problem.base.t0
    symmetric = all(ph.bank_range[0] == -ph.bank_range[1] for ph in problem.phases)
    # key -> per phase (values deg, limit deg, middle deg)
    checks: dict[str, list[tuple[PhaseSamples, Array, float, float]]] = {}
    for s in samples:
        phase = problem.phases[s.phase]
        bank = np.degrees(s.u[:, 1])
        low, high = (math.degrees(b) for b in phase.bank_range)
        if symmetric:
            checks.setdefault("bank_deg", []).append((s, np.abs(bank), high, 0.0))
        else:
            middle = 0.5 * (low + high)
            checks.setdefault("bank_deg", []).append((s, bank, high, middle))
            checks.setdefault("bank_min_deg", []).append((s, bank, low, middle))
        alpha = np.degrees(s.u[:, 0])
        low, high = (math.degrees(a) for a in phase.alpha_range)
        middle = 0.5 * (low + high)
        checks.setdefault("alpha_max_deg", []).append((s, alpha, high, middle))
        checks.setdefault("alpha_min_deg", []).append((s, alpha, low, middle))
    peaks: dict[str, Any] = {}
    ok = True
    for key, per_phase in checks.items():
        best: dict[str, Any] | None = None
        for s, values, limit, middle in per_phase:
            if values.size == 0:
                continue
            share = (values - middle) / (limit - middle)  # <= 1 within the bound, either side
            at = int(np.argmax(share))
            ratio = float(share[at])
            if best is None or ratio > best["ratio"]:
                best = {
                    "max": float(values[at]),
                    "at_time_s": float(s.t[at] * ts + t0),
                    "limit": limit,
                    "ratio": ratio,
                    "within": bool(ratio <= 1.0 + tol.control_limit_relative),
                    "phase": problem.phases[s.phase].name,
                }
        if best is not None:
            ok &= best["within"]
            peaks[key] = best
    return peaks, ok


def _zones(
    problem: PhasedProblem, y: Array, tol: VerificationTolerances
) -> tuple[list[dict[str, Any]], bool]:
    """Each no-fly zone's smallest clearance on the dense flown path (as ``verification``)."""
    sc = problem.base.scales
    zones = []
    ok = True
    for z in problem.base.no_fly_zones:
        d = zone_distance(y[:, 2], y[:, 1], z).c - z.radius
        clearance_deg = math.degrees(float(np.min(d)))
        within = clearance_deg >= -tol.no_fly_zone_deg
        ok &= within
        zones.append(
            {
                "name": z.name,
                "min_clearance_deg": clearance_deg,
                "min_clearance_km": clearance_deg * math.pi / 180 * sc.radius_m / 1000,
                "within": within,
                "latitude_deg": math.degrees(z.latitude),
                "longitude_deg": math.degrees(z.longitude),
                "radius_deg": math.degrees(z.radius),
                "metric": z.metric,
            }
        )
    return zones, ok


def phased_columns(
    problem: PhasedProblem, t: Array, x: Array, u: Array, path: dict[str, Array], phase: Array
) -> dict[str, Array]:
    """Rows of a phased flight (nodes or dense samples) as named columns, SI and degrees: the
    single-phase columns, then mass, thrust acting and commanded (with propulsion) and the
    phase index."""
    sc = problem.base.scales
    cols: dict[str, Array] = {
        "time_s": t * sc.time_s + problem.base.t0,
        "altitude_m": (x[:, 0] - 1.0) * sc.radius_m,
        "longitude_deg": np.degrees(x[:, 1]),
        "latitude_deg": np.degrees(x[:, 2]),
        "velocity_m_s": x[:, 3] * sc.speed_m_s,
        "flight_path_angle_deg": np.degrees(x[:, 4]),
        "heading_deg": np.degrees(x[:, 5]),
        "bank_deg": np.degrees(u[:, 1]),
        "alpha_deg": np.degrees(u[:, 0]),
    }
    if flight_heat_model(problem) is not None:
        cols["heat_rate_W_m2"] = path["heat_rate_W_m2"]
    cols["dynamic_pressure_Pa"] = path["dynamic_pressure_Pa"]
    cols["load_factor_g"] = path["load_factor_g"]
    if problem.model.thruster is not None:
        cols["mass_kg"] = x[:, 6] * problem.mass_kg
        cols["thrust_n"] = problem.model.thrust(x, u) * problem.thrust_unit_n
        cols["thrust_command_n"] = u[:, 2] * problem.thrust_unit_n
    cols["phase"] = np.asarray(phase, dtype=int)
    return cols


def _propagated(problem: PhasedProblem, samples: list[PhaseSamples]) -> dict[str, Any]:
    """The dense flown rows of every phase as columns, thinned with ``sample_rows`` (every path,
    bank and alpha peak, each zone's closest approach and each phase's first and last row
    kept)."""
    t = np.concatenate([s.t for s in samples])
    x = np.concatenate([s.x for s in samples])
    u = np.concatenate([s.u for s in samples])
    path = {key: np.concatenate([s.path[key] for s in samples]) for key in PATH_KEYS}
    phase = np.concatenate([np.full(s.t.size, s.phase) for s in samples])
    cols = phased_columns(problem, t, x, u, path, phase)
    peaks = [cols[k] for k in PATH_KEYS if k in cols]
    peaks += [np.abs(cols["bank_deg"]), cols["alpha_deg"], -cols["alpha_deg"]]
    if "thrust_n" in cols:
        peaks.append(cols["thrust_n"])
    for zone in (*problem.base.no_fly_zones, *problem.base.waypoints):
        peaks.append(-zone_distance(x[:, 2], x[:, 1], zone).c)
    rows = sample_rows(t.size, [p for p in peaks if p.size])
    sizes = np.cumsum([s.t.size for s in samples])
    edges = np.concatenate([sizes - np.array([s.t.size for s in samples]), sizes - 1])
    rows = np.unique(np.concatenate([rows, edges[edges >= 0]]))
    out: dict[str, Any] = {k: v[rows].tolist() for k, v in cols.items()}
    out["units"] = {k: COLUMN_UNITS[k] for k in cols}
    out["samples"] = int(rows.size)
    return out


def verify_phased(
    problem: PhasedProblem,
    traj: PhasedTrajectory,
    tolerances: VerificationTolerances | None = None,
    samples_per_interval: int = 20,
    should_stop: StopCheck | None = None,
) -> dict[str, Any]:
    """Propagate ``traj``'s controls through every phase and report, as ``verification.verify``
    does, errors, path maxima, zone clearance, control bounds and feasibility, plus each phase's
    end (``phases``).

    Raises ``verification.VerificationStoppedError`` when ``should_stop`` answers true while
    propagating.
    """
    tol = tolerances or VerificationTolerances()
    base = problem.base
    sc = base.scales
    flights = propagate_phased(problem, traj, should_stop=should_stop)
    reached_end = len(flights) == len(problem.phases) and all(f.reached_end for f in flights)
    last = flights[-1]
    t_final = last.end
    final_si = state_si(problem, last.x_end)

    phases: list[dict[str, Any]] = []
    phases_ok = True
    for flight in flights:
        phase = problem.phases[flight.index]
        end_si = state_si(problem, flight.x_end)
        checks, within = end_checks(phase.end_si, end_si, tol)
        phases_ok &= within and flight.reached_end
        phases.append(
            {
                "name": phase.name,
                "start_time_s": flight.start * sc.time_s + base.t0,
                "end_time_s": flight.end * sc.time_s + base.t0,
                "reached_end": flight.reached_end,
                "end_state": end_si,
                "end_error_vs_target": checks,
                "within": within,
            }
        )
    # the last phase's end, as the single-phase report's terminal check (decided by reached_end
    # when the ground ended the flight before the last phase)
    terminal_vs_target, _ = end_checks(problem.phases[-1].end_si, final_si, tol)

    opt_final_si = state_si(problem, traj.x[-1])
    terminal_vs_opt: dict[str, float] = {
        name: final_si[name] - opt_final_si[name] for name in final_si
    }
    terminal_vs_opt["time_s"] = (t_final - float(traj.t[-1])) * sc.time_s

    samples = [_samples(problem, traj, f, samples_per_interval) for f in flights]
    path, path_ok = _path_maxima(problem, samples, tol)
    controls, controls_ok = _control_peaks(problem, samples, tol)
    t_all = np.concatenate([s.t for s in samples])
    y_all = np.concatenate([s.x[:, :6] for s in samples])
    zones, zones_ok = _zones(problem, y_all, tol)
    waypoints, waypoints_ok = waypoint_passes(base, t_all, y_all, tol)

    heat_load = None
    if flight_heat_model(problem) is not None:
        heat_load = float(
            sum(np.trapezoid(s.path["heat_rate_W_m2"], s.t) for s in samples) * sc.time_s
        )
    feasible = bool(
        reached_end and phases_ok and path_ok and zones_ok and controls_ok and waypoints_ok
    )
    return {
        "feasible": feasible,
        "reached_end": bool(reached_end),
        "integrator": {
            "method": "DOP853",
            "rtol": RTOL,
            "atol": ATOL,
            "steps": int(sum(f.steps for f in flights)),
        },
        "tolerances": asdict(tol),
        "final_state": {**final_si, "time_s": t_final * sc.time_s + base.t0},
        "terminal_error_vs_target": terminal_vs_target,
        "terminal_error_vs_optimized": terminal_vs_opt,
        "max_deviation_along_path": _deviation(problem, traj, flights),
        "path_maxima": path,
        "no_fly_zones": zones,
        "control_limits": controls,
        "heat_load_J_m2": heat_load,
        "propagated": _propagated(problem, samples),
        **({"waypoints": waypoints} if waypoints else {}),
        "phases": phases,
    }
