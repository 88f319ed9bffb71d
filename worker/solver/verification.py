"""Verification: integrate the returned controls through the full nonlinear time-domain dynamics.

Applied to every result of every method. The bank profile is interpolated linearly in the
method's own independent variable (energy for energy-domain methods, time otherwise), or, when
the method gives the bank rate at the nodes (bank as a state with a first-order-hold rate), the
bank is integrated exactly from each node (piecewise quadratic in time); it is evaluated
on the propagated state, and the integration (scipy DOP853, rtol 1e-10) stops where the method's
trajectory ends (final energy or final time). The report compares the propagated end state with
the targets and with the optimized trajectory, measures the largest deviation along the path,
the path-limit maxima on a dense grid between nodes, the no-fly-zone clearance, and the flown
bank (and bank rate) against the control limits on the same grid.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from worker.solver.constraints.no_fly import zone_distance
from worker.solver.models import flown_rates
from worker.solver.models.bank_state_compiled import compiled_parameters, float_arrays
from worker.solver.models.lift_vector import lift_controls, lift_vector_dynamics
from worker.solver.models.point_mass import time_dynamics
from worker.solver.models.scalar_rates import time_rates
from worker.solver.path_limits import path_values
from worker.solver.problem import EntryProblem, TerminalTarget
from worker.solver.trajectory import (
    TIME_STATE_NAMES,
    Array,
    OptimizedTrajectory,
    bank_profile,
    bank_profile_at,
    bank_rate_at,
)
from worker.solver.units import COLUMN_UNITS

StopCheck = Callable[[], bool]

RTOL = 1e-10
"""Relative tolerance of the propagation: the states are nondimensional (r ~ 1, V ~ 1), so with
``ATOL`` the integration error is about a millimetre and 1e-6 m/s over a flight, at least 10^5
times below the tolerances it checks (500 m, 10 m/s, 0.1 deg; docs/methods/README.md)."""
ATOL = 1e-12
"""Absolute tolerance of the propagation (nondimensional states)."""
STOP_POLL_INTERVAL_S = 0.2
MAX_PATH_SAMPLES = 300
"""About how many rows of the dense propagated flight a result keeps (``propagated``): a
smooth curve on an 800-pixel plot, about 40 kB of a result document (its service overhead
measured: 1 000 rows cost 7 ms a job, docs/service.md)."""
"""How often a propagation asks its stop check (wall seconds): a cancel or a time limit ends a
long verification within about this long, without a database read per right-hand side."""


class VerificationStoppedError(Exception):
    """The stop check answered true during the propagation (cancel or time limit)."""


def poller(should_stop: StopCheck | None) -> Callable[[], None]:
    """A cheap call for the right-hand side: asks ``should_stop`` at its first call, then at
    most every poll interval, and raises :class:`VerificationStoppedError` when it answers
    true."""
    if should_stop is None:
        return lambda: None
    due = time.monotonic()  # the first call asks: a stop already requested is seen at once

    def poll() -> None:
        nonlocal due
        now = time.monotonic()
        if now < due:
            return
        due = now + STOP_POLL_INTERVAL_S
        if should_stop():
            raise VerificationStoppedError

    return poll


@dataclass(frozen=True)
class VerificationTolerances:
    """What 'feasible' means: terminal errors, relative path-limit excess, zone intrusion and
    relative excess of the flown bank (and bank rate) over the problem's control limits; and
    how far the flown objective may exceed the optimized one (``api``'s objective check)."""

    altitude_m: float = 500.0
    longitude_deg: float = 0.1
    latitude_deg: float = 0.1
    velocity_m_s: float = 10.0
    flight_path_angle_deg: float = 0.3
    heading_deg: float = 0.3
    path_limit_relative: float = 0.01
    no_fly_zone_deg: float = 0.05
    control_limit_relative: float = 0.01
    objective_relative: float = 0.01


def _energy(y: Array) -> Array:
    return 1.0 / y[0] - 0.5 * y[3] ** 2


def terminal_error(spec: TerminalTarget, value: float) -> float:
    """Signed miss of ``value`` from a fixed or soft target, or its distance outside a range."""
    if spec.kind == "range":
        assert spec.lo is not None and spec.hi is not None
        return max(spec.lo - value, value - spec.hi, 0.0)
    assert spec.value is not None
    return value - spec.value


def to_si(problem: EntryProblem, y: Array) -> dict[str, float]:
    """One time-form state in the API's units."""
    return {
        "altitude_m": float((y[0] - 1.0) * problem.scales.radius_m),
        "longitude_deg": math.degrees(y[1]),
        "latitude_deg": math.degrees(y[2]),
        "velocity_m_s": float(y[3] * problem.scales.speed_m_s),
        "flight_path_angle_deg": math.degrees(y[4]),
        "heading_deg": math.degrees(y[5]),
    }


@dataclass
class Propagation:
    """The propagated trajectory: the integrator's solution of each segment between restarts,
    joined. ``sol(t)`` evaluates the integrators' own dense output (of the segment holding t)."""

    segments: list[Any]
    status: int  # 0: the end time was reached; 1: a terminal event ended the flight
    events: int  # how many event functions each segment had

    @property
    def t(self) -> Array:
        """Every accepted step's time, the segments' shared ends once."""
        parts = [self.segments[0].t] + [seg.t[1:] for seg in self.segments[1:]]
        return np.concatenate(parts)

    @property
    def y(self) -> Array:
        """The states at ``t`` (6, M)."""
        parts = [self.segments[0].y] + [seg.y[:, 1:] for seg in self.segments[1:]]
        return np.concatenate(parts, axis=1)

    @property
    def t_events(self) -> list[Array]:
        """Per event function, the times it fired at (terminal: at most once, at the end)."""
        return [
            np.concatenate([seg.t_events[i] for seg in self.segments]) for i in range(self.events)
        ]

    @property
    def steps(self) -> int:
        """Accepted integrator steps over all segments."""
        return int(sum(seg.t.size - 1 for seg in self.segments))

    def sol(self, t: Array) -> Array:
        """States (n_states, len(t)) at times ``t`` within the flight, from the dense outputs."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        ends = np.array([seg.t[-1] for seg in self.segments])
        which = np.minimum(np.searchsorted(ends, t, side="left"), len(self.segments) - 1)
        out = np.empty((self.segments[0].y.shape[0], t.size))
        for k in np.unique(which):
            mask = which == k
            out[:, mask] = self.segments[k].sol(t[mask])
        return out


def _rhs(
    problem: EntryProblem, traj: OptimizedTrajectory, poll: Callable[[], None]
) -> Callable[[float, Array], Array]:
    """The time-domain right-hand side under the flown bank: compiled (``models.flown_rates``)
    for the compiled force models and a scheduled angle of attack, else in Python."""
    forces, omega = problem.forces, problem.omega
    grid = traj.grid
    alpha_nodes = traj.alpha_deg
    by_energy = traj.grid_kind == "energy"
    # a continuous attitude path is flown as the method represents it, in Python
    nodal = alpha_nodes is None and traj.attitude is None
    params = compiled_parameters(forces, omega) if nodal else None
    if params is not None:
        if by_energy:
            kind = flown_rates.LINEAR_IN_ENERGY
        elif traj.bank_rate is not None:
            kind = flown_rates.HOLD_IN_TIME
        else:
            kind = flown_rates.LINEAR_IN_TIME
        rate = traj.bank_rate if traj.bank_rate is not None else traj.bank
        g, b, w = float_arrays(grid, traj.bank, rate)
        kernel = flown_rates.flown_rates

        def compiled(t: float, y: Array) -> Array:
            poll()
            return kernel(t, y, kind, g, b, w, params)

        return compiled
    u = np.zeros((1, 2))
    attitude = traj.attitude
    if attitude is not None:  # bank and alpha as the method represents them between nodes
        at = np.zeros(1)
        scheduled = forces.alpha_schedule is not None  # the schedule's alpha, not the path's

        def flown(t: float, y: Array) -> Array:
            poll()
            at[0] = t
            sigma, alpha = attitude.at(at)
            u[0, 0], u[0, 1] = math.cos(sigma[0]), math.sin(sigma[0])
            alpha_arg = None if scheduled else alpha
            return time_dynamics(y[None, :], u, forces, omega, alpha_arg, jacobians=False).f[0]

        if problem.planet_model == "flat":  # paper 001 eq. 1, the normalized lift in alpha's place

            def flown_flat(t: float, y: Array) -> Array:
                poll()
                at[0] = t
                sigma, lam = attitude.at(at)
                lift = lift_controls(lam, sigma)
                return lift_vector_dynamics(y[None, :], lift, forces, 0.0, "flat",
                                            jacobians=False).f[0]  # fmt: skip

            return flown_flat
        return flown

    def python(t: float, y: Array) -> Array:
        poll()
        s = _energy(y) if by_energy else t
        sigma = bank_profile(traj, s)
        if alpha_nodes is None:  # scheduled alpha: the scalar fast path
            _, lift, drag, _ = forces.lift_drag(y[0], y[3])  # numpy scalars: no array overhead
            return time_rates(y, math.cos(sigma), math.sin(sigma), float(lift), float(drag), omega)
        u[0, 0], u[0, 1] = math.cos(sigma), math.sin(sigma)
        alpha = np.array([np.interp(s, grid, alpha_nodes)])
        return time_dynamics(y[None, :], u, forces, omega, alpha, jacobians=False).f[0]

    return python


def propagate(
    problem: EntryProblem,
    traj: OptimizedTrajectory,
    *,
    rtol: float = RTOL,
    atol: float = ATOL,
    should_stop: StopCheck | None = None,
) -> Propagation:
    """Integrate the time-domain dynamics under the trajectory's bank profile (DOP853).

    The integration restarts at every node's time: the flown control has a kink there (its
    slope, or its rate's, jumps; a path smooth between nodes that says where its pieces meet,
    ``breaks``, restarts there only), which an adaptive step that crosses it meets with rejected
    steps; from the node on, each segment starts clean (measured: 25 000 right-hand sides for
    the built-in energy case without restarts, 5 500 with). An energy-grid trajectory restarts
    at its nodes' optimized times (the flown ones differ by the verification's own error) and
    ends where the energy reaches its final value; a time-grid one ends at its final time. The
    ground ends either. ``should_stop`` is asked every :data:`STOP_POLL_INTERVAL_S`; a true
    answer raises :class:`VerificationStoppedError`.
    """
    grid = traj.grid
    by_energy = traj.grid_kind == "energy"
    rhs = _rhs(problem, traj, poller(should_stop))

    def ground(t: float, y: Array) -> float:
        return float(y[0] - 1.0)

    ground.terminal = True  # type: ignore[attr-defined]
    events: list[Any] = [ground]
    if by_energy:
        e_final = float(grid[-1])

        def final_energy(t: float, y: Array) -> float:
            return float(_energy(y) - e_final)

        final_energy.terminal = True  # type: ignore[attr-defined]
        final_energy.direction = 1.0  # type: ignore[attr-defined]
        events.append(final_energy)
        t_end = 3.0 * float(traj.t[-1]) + 1.0
        stops = [float(t) for t in traj.t[1:-1] if 0.0 < t < t_end] + [t_end]
    else:
        t_end = float(grid[-1])
        kinks = getattr(traj.attitude, "breaks", None)  # where a smooth path's pieces meet
        restarts = traj.t[1:-1] if kinks is None else kinks
        stops = [float(t) for t in restarts if 0.0 < t < t_end] + [t_end]
    segments, status = propagate_in_pieces(
        rhs, 0.0, np.asarray(problem.y0, dtype=float), stops, rtol, atol, events
    )
    return Propagation(segments=segments, status=status, events=len(events))


def propagate_in_pieces(
    rhs: Any,
    t0: float,
    y0: Array,
    stops: list[float],
    rtol: float,
    atol: float,
    events: list[Any],
) -> tuple[list[Any], int]:
    """DOP853 from (t0, y0), restarted at each of ``stops`` (where the controls' pieces meet:
    no step straddles a kink), until the last stop or an event: the dense segments and
    solve_ivp's status of the last one (0: reached the end)."""
    segments: list[Any] = []
    t_start, y = t0, y0
    for t_stop in stops:
        if t_stop <= t_start:
            continue
        segment = solve_ivp(
            rhs, (t_start, t_stop), y, method="DOP853", rtol=rtol, atol=atol, events=events,
            dense_output=True,
        )  # fmt: skip
        segments.append(segment)
        t_start, y = float(segment.t[-1]), segment.y[:, -1]
        if segment.status != 0:  # an event ended the flight (or the integrator failed)
            return segments, int(segment.status)
    return segments, 0


def verify(
    problem: EntryProblem,
    traj: OptimizedTrajectory,
    tolerances: VerificationTolerances | None = None,
    samples_per_interval: int = 20,
    should_stop: StopCheck | None = None,
) -> dict[str, Any]:
    """Propagate ``traj``'s controls and report errors, path maxima, zone clearance, feasibility.

    Raises :class:`VerificationStoppedError` when ``should_stop`` answers true while propagating.
    """
    tol = tolerances or VerificationTolerances()
    sol = propagate(problem, traj, should_stop=should_stop)
    sc = problem.scales
    t_final = float(sol.t[-1])
    y_final = sol.y[:, -1]
    reached_end = sol.status == 1 and (len(sol.t_events) > 1 and sol.t_events[-1].size > 0)
    if traj.grid_kind == "time":
        reached_end = sol.status == 0
    final_si = to_si(problem, y_final)
    opt_final_si = to_si(problem, traj.y[-1])
    tol_map = {name: getattr(tol, name) for name in TIME_STATE_NAMES}

    terminal_vs_target: dict[str, Any] = {}
    hard_ok = True
    for name in TIME_STATE_NAMES:
        spec = problem.terminal_si[name]
        value = final_si[name]
        if spec.kind == "free":
            continue
        err = terminal_error(spec, value)
        within = abs(err) <= tol_map[name]
        if spec.kind in ("fixed", "range"):
            hard_ok &= within
        terminal_vs_target[name] = {
            "kind": spec.kind,
            "error": err,
            "tolerance": tol_map[name],
            "within": within,
        }

    terminal_vs_opt = {name: final_si[name] - opt_final_si[name] for name in TIME_STATE_NAMES}
    terminal_vs_opt["time_s"] = (t_final - float(traj.t[-1])) * sc.time_s

    # deviation along the path at the optimizer's nodes
    if traj.grid_kind == "energy":
        t_dense = np.linspace(0.0, t_final, 40 * traj.grid.size)
        e_dense = _energy(sol.sol(t_dense))
        order = np.maximum.accumulate(e_dense)  # energy increases; guard against tiny wiggles
        t_nodes = np.interp(traj.grid, order, t_dense)
    else:
        t_nodes = np.clip(traj.grid, 0.0, t_final)
    y_nodes = sol.sol(t_nodes).T
    dev = np.abs(y_nodes - traj.y)
    deviation = {
        "altitude_m": float(np.max(dev[:, 0]) * sc.radius_m),
        "longitude_deg": math.degrees(np.max(dev[:, 1])),
        "latitude_deg": math.degrees(np.max(dev[:, 2])),
        "velocity_m_s": float(np.max(dev[:, 3]) * sc.speed_m_s),
        "flight_path_angle_deg": math.degrees(np.max(dev[:, 4])),
        "heading_deg": math.degrees(np.max(dev[:, 5])),
    }

    # path limits on a dense grid between the nodes of the propagated trajectory
    t_fine = np.unique(
        np.concatenate(
            [np.linspace(a, b, samples_per_interval + 1) for a, b in itertools.pairwise(t_nodes)]
        )
    )
    t_fine = t_fine[t_fine <= t_final]
    y_fine = sol.sol(t_fine).T
    s_fine = _energy(y_fine.T) if traj.grid_kind == "energy" else t_fine
    alpha = None
    if traj.attitude is not None and problem.forces.alpha_schedule is None:
        alpha = traj.attitude.at(t_fine)[1]
    elif traj.alpha_deg is not None:
        alpha = np.interp(s_fine, traj.grid, traj.alpha_deg)
    ft = problem.forces.terms(y_fine[:, 0], y_fine[:, 3], alpha)
    pv = path_values(problem.forces, problem.heat_model, y_fine[:, 0], y_fine[:, 3], ft)
    lim = problem.limits
    path: dict[str, Any] = {}
    path_ok = True
    for key, values, limit in (
        ("heat_rate_W_m2", pv.heat_rate if problem.heat_model else None, lim.heat_max_W_m2),
        ("dynamic_pressure_Pa", pv.dynamic_pressure, lim.dynamic_pressure_max_Pa),
        ("load_factor_g", pv.load_factor, lim.load_factor_max_g),
    ):
        if values is None:
            continue
        peak = float(np.max(values))
        entry: dict[str, Any] = {
            "max": peak,
            "at_time_s": float(t_fine[int(np.argmax(values))] * sc.time_s + problem.t0),
        }
        if limit is not None:
            entry["limit"] = limit
            entry["ratio"] = peak / limit
            entry["within"] = peak <= limit * (1.0 + tol.path_limit_relative)
            path_ok &= entry["within"]
        path[key] = entry

    zones = []
    zones_ok = True
    for z in problem.no_fly_zones:
        d = zone_distance(y_fine[:, 2], y_fine[:, 1], z).c - z.radius
        clearance_deg = math.degrees(float(np.min(d)))
        ok = clearance_deg >= -tol.no_fly_zone_deg
        zones_ok &= ok
        zones.append(
            {
                "name": z.name,
                "min_clearance_deg": clearance_deg,
                "min_clearance_km": clearance_deg * math.pi / 180 * sc.radius_m / 1000,
                "within": ok,
                "latitude_deg": math.degrees(z.latitude),
                "longitude_deg": math.degrees(z.longitude),
                "radius_deg": math.degrees(z.radius),
                "metric": z.metric,
            }
        )

    bank = bank_profile_at(traj, s_fine)  # the flown bank, read by the checks and the columns
    controls, controls_ok = _control_peaks(problem, traj, t_fine, s_fine, tol, bank)
    waypoints, waypoints_ok = waypoint_passes(problem, t_fine, y_fine, tol)

    heat_load = None
    if problem.heat_model is not None:
        q_nodes = pv.heat_rate
        heat_load = float(np.trapezoid(q_nodes, t_fine) * sc.time_s)
    feasible = bool(
        reached_end and hard_ok and path_ok and zones_ok and controls_ok and waypoints_ok
    )
    return {
        "feasible": feasible,
        "reached_end": bool(reached_end),
        "integrator": {"method": "DOP853", "rtol": RTOL, "atol": ATOL, "steps": sol.steps},
        "tolerances": asdict(tol),
        "final_state": {**final_si, "time_s": t_final * sc.time_s + problem.t0},
        "terminal_error_vs_target": terminal_vs_target,
        "terminal_error_vs_optimized": terminal_vs_opt,
        "max_deviation_along_path": deviation,
        "path_maxima": path,
        "no_fly_zones": zones,
        "control_limits": controls,
        "heat_load_J_m2": heat_load,
        "propagated": propagated_columns(problem, traj, t_fine, bank, y_fine, ft.alpha_deg, pv),
        **({"waypoints": waypoints} if waypoints else {}),
    }


def waypoint_passes(
    problem: EntryProblem, t_fine: Array, y_fine: Array, tol: VerificationTolerances
) -> tuple[list[dict[str, Any]], bool]:
    """Each waypoint's closest approach on the dense flown path, in order: it is passed when
    the path comes within its radius (with the zones' margin), after the previous waypoint's
    closest approach."""
    sc = problem.scales
    passes: list[dict[str, Any]] = []
    ok = True
    after = 0
    for point in problem.waypoints:
        distance = zone_distance(y_fine[after:, 2], y_fine[after:, 1], point).c
        at = after + int(np.argmin(distance))
        closest = math.degrees(float(distance[at - after]))
        passed = closest <= math.degrees(point.radius) + tol.no_fly_zone_deg
        ok &= passed
        passes.append(
            {
                "order": point.order,
                "latitude_deg": math.degrees(point.latitude),
                "longitude_deg": math.degrees(point.longitude),
                "radius_deg": math.degrees(point.radius),
                "metric": point.metric,
                "closest_deg": closest,
                "at_time_s": float(t_fine[at] * sc.time_s + problem.t0),
                "within": passed,
            }
        )
        after = at
    return passes, ok


def sample_rows(count: int, peaks: list[Array], limit: int = MAX_PATH_SAMPLES) -> Array:
    """Indices of at most about ``limit`` of ``count`` dense samples, evenly strided, with the
    last sample and the position of each array's maximum in ``peaks`` kept, so that a curve
    drawn through them reaches the peaks the checks report."""
    stride = max(1, math.ceil(count / limit))
    keep = [np.arange(0, count, stride), np.array([count - 1])]
    keep.extend(np.array([int(np.argmax(values))]) for values in peaks)
    return np.unique(np.concatenate(keep))


def lift_control_column(problem: EntryProblem) -> str:
    """The column of the lift control: the normalized lift of a parabolic polar (which takes
    the angle of attack's place in the force models), else the angle of attack."""
    return "normalized_lift" if problem.lift_range is not None else "alpha_deg"


def propagated_columns(
    problem: EntryProblem,
    traj: OptimizedTrajectory,
    t_fine: Array,
    bank_rad: Array,
    y_fine: Array,
    alpha_deg: Array,
    pv: Any,
) -> dict[str, Any]:
    """The propagated flight on the dense grid the checks read (thinned to at most about
    :data:`MAX_PATH_SAMPLES` rows, every path and bank peak and each zone's and waypoint's
    closest approach kept) as named columns in SI units and degrees, the same names as the
    optimized trajectory's: what a plot overlays on the nodes."""
    sc = problem.scales
    bank = np.degrees(bank_rad)
    alpha = np.broadcast_to(np.asarray(alpha_deg, dtype=float), t_fine.shape)
    columns: dict[str, Array | None] = {
        "time_s": t_fine * sc.time_s + problem.t0,
        "altitude_m": (y_fine[:, 0] - 1.0) * sc.radius_m,
        "longitude_deg": np.degrees(y_fine[:, 1]),
        "latitude_deg": np.degrees(y_fine[:, 2]),
        "velocity_m_s": y_fine[:, 3] * sc.speed_m_s,
        "flight_path_angle_deg": np.degrees(y_fine[:, 4]),
        "heading_deg": np.degrees(y_fine[:, 5]),
        "bank_deg": bank,
        lift_control_column(problem): alpha,
        "heat_rate_W_m2": pv.heat_rate if problem.heat_model else None,
        "dynamic_pressure_Pa": pv.dynamic_pressure,
        "load_factor_g": pv.load_factor,
    }
    present = {k: np.asarray(v, dtype=float) for k, v in columns.items() if v is not None}
    path_keys = ("heat_rate_W_m2", "dynamic_pressure_Pa", "load_factor_g")
    peaks = [present[k] for k in path_keys if k in present]  # no heat rate without its model
    peaks.append(np.abs(bank))
    if problem.bank_rate_max is not None:  # the flown bank rate's peak (control_limits)
        peaks.append(np.abs(bank_rate_at(traj, t_fine, bank_rad)))
    for zone in (*problem.no_fly_zones, *problem.waypoints):  # each closest approach
        peaks.append(-zone_distance(y_fine[:, 2], y_fine[:, 1], zone).c)
    rows = sample_rows(t_fine.size, [p for p in peaks if p.size])
    out: dict[str, Any] = {k: v[rows].tolist() for k, v in present.items()}
    out["units"] = {k: COLUMN_UNITS[k] for k in present}
    out["samples"] = int(rows.size)
    return out


def _control_peaks(
    problem: EntryProblem,
    traj: OptimizedTrajectory,
    t_fine: Array,
    s_fine: Array,
    tol: VerificationTolerances,
    bank: Array | None = None,
) -> tuple[dict[str, Any], bool]:
    """The largest |bank| (and |bank rate|, when the problem limits it) of the flown control on
    the dense grid, against the problem's limits; and whether both hold. A method bounds its
    controls at the nodes; between them the flown profile (quadratic in time under a
    first-order-hold rate) may turn beyond the limit, which only this check sees. An asymmetric
    bank range is checked on both sides: the largest bank against the upper bound (``bank_deg``)
    and the smallest against the lower (``bank_min_deg``), each ratio the share of the range's
    half-width used from its middle (for a symmetric range, |bank| / limit)."""
    sc = problem.scales
    if bank is None:  # the flown bank on the grid, unless the caller has it already
        bank = bank_profile_at(traj, s_fine)
    low, high = math.degrees(problem.bank_min), math.degrees(problem.bank_max)
    checks: list[tuple[str, Array, float, float]] = []
    if low == -high:
        checks.append(("bank_deg", np.degrees(np.abs(bank)), high, 0.0))
    else:
        checks.append(("bank_deg", np.degrees(bank), high, 0.5 * (low + high)))
        checks.append(("bank_min_deg", np.degrees(bank), low, 0.5 * (low + high)))
    if problem.bank_rate_max is not None:
        rate = np.abs(bank_rate_at(traj, t_fine, bank))
        per_s = math.degrees(1.0) / sc.time_s
        checks.append(("bank_rate_deg_s", rate * per_s, problem.bank_rate_max * per_s, 0.0))
    checks.extend(_alpha_checks(problem, traj, t_fine))
    peaks: dict[str, Any] = {}
    ok = True
    for key, values, limit, middle in checks:
        share = (values - middle) / (limit - middle)  # <= 1 within the limit, on either side
        at = int(np.argmax(share))
        ratio = float(share[at])
        within = bool(ratio <= 1.0 + tol.control_limit_relative)
        ok &= within
        peaks[key] = {
            "max": float(values[at]),
            "at_time_s": float(t_fine[at] * sc.time_s + problem.t0),
            "limit": limit,
            "ratio": ratio,
            "within": within,
        }
    return peaks, ok


def _alpha_checks(
    problem: EntryProblem, traj: OptimizedTrajectory, t_fine: Array
) -> list[tuple[str, Array, float, float]]:
    """The flown angle of attack against an optimized one's bounds (both sides, as the bank's
    asymmetric range) and its rate against the rate bound, on the dense grid (degrees)."""
    if traj.attitude is None or problem.alpha_range is None:
        return []
    _, alpha = traj.attitude.at(t_fine)
    low, high = (math.degrees(a) for a in problem.alpha_range)
    middle = 0.5 * (low + high)
    checks = [("alpha_max_deg", alpha, high, middle), ("alpha_min_deg", alpha, low, middle)]
    if problem.alpha_rate_max is not None:
        per_s = math.degrees(1.0) / problem.scales.time_s
        rate = np.abs(traj.attitude.rates_at(t_fine)[1]) * per_s
        checks.append(("alpha_rate_deg_s", rate, problem.alpha_rate_max * per_s, 0.0))
    return checks
