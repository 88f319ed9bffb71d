"""The Chebyshev SCvx's initial reference: the route through the waypoints to the target, or the
constant-control flight (paper 001 step 1: lam = 1, sigma = 0) when there is no target point.

With a target the states run along the route (great circles on the sphere, straight lines on the
flat map) at the arc-length share of each point, altitude, speed and flight-path angle from their
initial values to their terminal targets, heading along the route; the best lift-to-drag lam
(1 for a polar) and sigma = 0 fly every point. The flight time is the route length at the mean
of the initial and terminal speeds.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from worker.solver.methods.cheb_scvx.linearization import ChebIterate
from worker.solver.methods.cheb_scvx.segments import Segments
from worker.solver.models.lift_vector import PlanetModel, glide_share, lift_vector_dynamics
from worker.solver.models.point_mass import GA, PH, PS, TH, R, V
from worker.solver.problem import EntryProblem

Array = np.ndarray
FREE_END_SHARE = 0.3
"""Without a terminal target, the guess ends at this share of the initial altitude and speed."""


def route_points(problem: EntryProblem) -> list[tuple[float, float]] | None:
    """(latitude, longitude) in radians of the start, each waypoint in order and the target;
    None without a target point."""
    lat, lon = problem.terminal["latitude_deg"].target(), problem.terminal["longitude_deg"].target()
    if lat is None or lon is None:
        return None
    start = (float(problem.y0[PH]), float(problem.y0[TH]))
    return [start, *((w.latitude, w.longitude) for w in problem.waypoints), (lat, lon)]


def leg_length(a: tuple[float, float], b: tuple[float, float], model: PlanetModel) -> float:
    """Angular length of a leg: the great-circle central angle, or the flat map distance."""
    if model == "flat":
        return math.hypot(b[0] - a[0], b[1] - a[1])
    s = (
        math.sin(0.5 * (b[0] - a[0])) ** 2
        + math.cos(a[0]) * math.cos(b[0]) * math.sin(0.5 * (b[1] - a[1])) ** 2
    )
    return 2.0 * math.asin(math.sqrt(min(max(s, 0.0), 1.0)))


def _unit_vector(p: tuple[float, float]) -> Array:
    """The unit vector of a (latitude, longitude) point."""
    lat, lon = p
    return np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])


def _along(
    a: tuple[float, float], b: tuple[float, float], f: Array, model: PlanetModel
) -> tuple[Array, Array, Array]:
    """Latitude, longitude and heading (clockwise from north) at fractions ``f`` of a leg."""
    if model == "flat":
        lat = a[0] + f * (b[0] - a[0])
        lon = a[1] + f * (b[1] - a[1])
        return lat, lon, np.full(f.shape, math.atan2(b[1] - a[1], b[0] - a[0]))
    pa = np.array(
        [math.cos(a[0]) * math.cos(a[1]), math.cos(a[0]) * math.sin(a[1]), math.sin(a[0])]
    )
    pb = np.array(
        [math.cos(b[0]) * math.cos(b[1]), math.cos(b[0]) * math.sin(b[1]), math.sin(b[0])]
    )
    omega = math.acos(float(np.clip(pa @ pb, -1.0, 1.0)))
    if omega < 1e-12:
        pts = np.repeat(pa[None, :], f.size, axis=0)
    else:
        pts = (
            np.sin((1.0 - f) * omega)[:, None] * pa + np.sin(f * omega)[:, None] * pb
        ) / math.sin(omega)
    lat = np.arcsin(np.clip(pts[:, 2], -1.0, 1.0))
    lon = np.arctan2(pts[:, 1], pts[:, 0])
    lon = a[1] + np.unwrap(lon - a[1])
    # heading towards b from each point (initial course of the remaining great circle)
    dlon = b[1] - lon
    head = np.arctan2(
        np.sin(dlon) * math.cos(b[0]),
        np.cos(lat) * math.sin(b[0]) - np.sin(lat) * math.cos(b[0]) * np.cos(dlon),
    )
    if f.size and f[-1] >= 1.0 and f.size > 1:
        head[-1] = head[-2]
    return lat, lon, head


def _end_value(problem: EntryProblem, key: str, free: float) -> float:
    target = problem.terminal[key].target()
    return float(target) if target is not None else free


def route_start(
    problem: EntryProblem,
    segments: Segments,
    route: list[tuple[float, float]],
    model: PlanetModel,
    flight_time: float | None,
) -> ChebIterate:
    """The route guess (see the module docstring)."""
    y0 = problem.y0
    lengths = [leg_length(a, b, model) for a, b in itertools.pairwise(route)]
    total = sum(lengths) or 1e-9
    r_end = _end_value(problem, "altitude_m", 1.0 + FREE_END_SHARE * (y0[R] - 1.0))
    v_end = _end_value(problem, "velocity_m_s", FREE_END_SHARE * y0[V])
    g_end = _end_value(problem, "flight_path_angle_deg", 0.0)
    if flight_time is None:
        flight_time = total / (0.5 * (y0[V] + v_end) / y0[R])
    legs = np.array([flight_time * max(L, 1e-6 * total) / total for L in lengths])
    durations = segments.durations(legs)
    done = np.concatenate([[0.0], np.cumsum(lengths)])
    y = np.empty((segments.state_points, 6))
    for s in range(segments.count):
        leg = segments.legs[s]
        within = segments.leg_intervals(leg)
        k = int(np.flatnonzero(within == s)[0])
        f = (k + 0.5 * (segments.tau(s) + 1.0)) / within.size
        sl = segments.states_of(s)
        lat, lon, head = _along(route[leg], route[leg + 1], f, model)
        share = (done[leg] + f * lengths[leg]) / total
        y[sl, PH], y[sl, TH], y[sl, PS] = lat, lon, head
        y[sl, R] = y0[R] + share * (r_end - y0[R])
        y[sl, V] = y0[V] + share * (v_end - y0[V])
        y[sl, GA] = np.where(share < 0.5, y0[GA] * (1 - 2 * share), g_end * (2 * share - 1))
    y[0] = y0
    lam = glide_share(problem.forces)
    u = np.tile([lam, 0.0, lam * lam], (segments.control_points, 1))
    return ChebIterate(y, u, durations)


def _floor_radius(problem: EntryProblem) -> float:
    """Radius where a start's glide ends: the terminal altitude (a range's floor), else a share
    of the initial altitude."""
    spec = problem.terminal["altitude_m"]
    if spec.kind == "range" and spec.lo is not None:
        return float(spec.lo)
    return _end_value(problem, "altitude_m", 1.0 + FREE_END_SHARE * (problem.y0[R] - 1.0))


def _glide_events(
    rhs: Callable[[float, Array], Array],
    r_end: float,
    point: tuple[float, float] | None,
    model: PlanetModel,
) -> list[Any]:
    """Terminal events of a start's glide: down to ``r_end``, and the closest approach to
    ``point`` (where the rate of the squared distance to it turns positive)."""

    def floor(t: float, y: Array) -> float:
        return float(y[R] - r_end)

    floor.terminal = True  # type: ignore[attr-defined]
    if point is None:
        return [floor]

    def closest(t: float, y: Array) -> float:
        f = rhs(t, y)
        factor = 1.0 if model == "flat" else math.cos(point[0]) ** 2
        return float((y[PH] - point[0]) * f[PH] + factor * (y[TH] - point[1]) * f[TH])

    closest.terminal = True  # type: ignore[attr-defined]
    closest.direction = 1.0  # type: ignore[attr-defined]
    return [floor, closest]


def propagated_start(
    problem: EntryProblem,
    segments: Segments,
    model: PlanetModel,
    flight_time: float | None,
    target: tuple[float, float] | None = None,
) -> ChebIterate:
    """The constant-control flight (lam = 1, sigma = 0; paper 001 step 1) sampled at the points
    of one leg: for ``flight_time``, else until the closest approach to ``target`` (or the
    terminal altitude, or a share of the initial one, whichever comes first)."""
    forces, omega = problem.forces, problem.omega
    lam = glide_share(forces)
    u_c = np.array([[lam, 0.0, lam * lam]])

    def rhs(t: float, y: Array) -> Array:
        return lift_vector_dynamics(y[None, :], u_c, forces, omega, model, jacobians=False).f[0]

    events = [] if flight_time else _glide_events(rhs, _floor_radius(problem), target, model)
    horizon = flight_time if flight_time is not None else 30.0
    sol = solve_ivp(rhs, (0.0, horizon), problem.y0, events=events or None,
                    dense_output=True, rtol=1e-8, atol=1e-10)  # fmt: skip
    tf = float(sol.t[-1])
    durations = segments.durations(np.array([tf]))
    y = sol.sol(segments.times(durations)).T
    u = np.tile(u_c[0], (segments.control_points, 1))
    return ChebIterate(y, u, durations)


def guess_start(problem: EntryProblem, segments: Segments) -> ChebIterate:
    """The caller's initial guess on one leg: its states and bank, lam = 1."""
    guess = problem.guess
    assert guess is not None
    tf = float(guess.t[-1])
    durations = segments.durations(np.array([tf]))
    y, _ = guess.on_times(segments.times(durations))
    _, bank = guess.on_times(segments.control_times(durations))
    y[0] = problem.y0
    lam = glide_share(problem.forces)
    u = np.column_stack([lam * np.cos(bank), lam * np.sin(bank), np.full_like(bank, lam * lam)])
    return ChebIterate(y, u, durations)


GUIDANCE_GAIN = 2.0
"""Bank (rad) per radian of heading error of the guided glide's steering towards the next point."""
OBJECTIVE_STEERING_GAIN = 0.8
"""Bank (rad) per radian of heading error of the start steered towards a final-position
objective's far point (``objective_point``): a banked turn that eases as the heading comes round
(-72 deg at 90 deg of error, as Betts' guess for the Shuttle's crossrange); the waypoint
guidance's gain of 2 banks to the limit and dives."""


def _course(y: Array, point: tuple[float, float], model: PlanetModel) -> float:
    """Heading (clockwise from north) from state ``y`` towards ``point``."""
    lat, lon = float(y[PH]), float(y[TH])
    if model == "flat":
        return math.atan2(point[1] - lon, point[0] - lat)
    dlon = point[1] - lon
    return math.atan2(
        math.sin(dlon) * math.cos(point[0]),
        math.cos(lat) * math.sin(point[0]) - math.sin(lat) * math.cos(point[0]) * math.cos(dlon),
    )


def guided_start(
    problem: EntryProblem,
    segments: Segments,
    route: list[tuple[float, float]],
    model: PlanetModel,
    *,
    reach: bool = True,
    gain: float = GUIDANCE_GAIN,
) -> ChebIterate | None:
    """A glide at the best lift-to-drag lam (``glide_share``) steered towards each point of the
    route in turn (bank proportional to the heading error, within the bank range), each leg
    ending at its point's closest approach: a dynamically consistent start through the
    waypoints, the legs' durations its times of arrival. None when the glide comes down before
    the last point (unless ``reach`` is false: then a leg may end where the glide comes down,
    the point only a direction to steer towards)."""
    forces, omega = problem.forces, problem.omega
    r_end = _floor_radius(problem)
    lam = glide_share(forces)

    def bank_towards(y: Array, point: tuple[float, float]) -> float:
        error = (_course(y, point, model) - float(y[PS]) + math.pi) % (2.0 * math.pi) - math.pi
        return min(max(gain * error, problem.bank_min), problem.bank_max)

    def controls(y: Array, point: tuple[float, float]) -> Array:
        bank = bank_towards(y, point)
        return np.array([[lam * math.cos(bank), lam * math.sin(bank), lam * lam]])

    legs, durations = [], []
    y0 = problem.y0.copy()
    for point in route[1:]:

        def rhs(t: float, y: Array, point: tuple[float, float] = point) -> Array:
            u = controls(y, point)
            return lift_vector_dynamics(y[None, :], u, forces, omega, model, jacobians=False).f[0]

        events = _glide_events(rhs, r_end, point, model)
        sol = solve_ivp(rhs, (0.0, 30.0), y0, events=events, dense_output=True,
                        rtol=1e-8, atol=1e-10, max_step=0.05)  # fmt: skip
        if (reach and sol.t_events[1].size == 0) or sol.t[-1] <= 0.0:
            return None
        legs.append((sol, point))
        durations.append(float(sol.t[-1]))
        y0 = sol.y[:, -1].copy()
    T = segments.durations(np.array(durations))
    starts = np.concatenate([[0.0], np.cumsum(durations)])
    y = np.empty((segments.state_points, 6))
    u = np.empty((segments.control_points, 3))
    times = segments.times(T)
    ctimes = segments.control_times(T)
    for s in range(segments.count):
        leg = segments.legs[s]
        sol, point = legs[leg]
        sl, cl = segments.states_of(s), segments.controls_of(s)
        y[sl] = sol.sol(np.clip(times[sl] - starts[leg], 0.0, durations[leg])).T
        ys = sol.sol(np.clip(ctimes[cl] - starts[leg], 0.0, durations[leg])).T
        u[cl] = np.vstack([controls(row, point) for row in ys])
    y[0] = problem.y0
    return ChebIterate(y, u, T)


def objective_point(problem: EntryProblem) -> tuple[float, float] | None:
    """Without a target point, a far point in the direction a final-position objective rewards
    (maximum final latitude: the north pole's side, 89 deg; longitude extremes: 90 deg of
    longitude away along the initial latitude), for a start steered towards it; None for
    other objectives."""
    lat0, lon0 = float(problem.y0[PH]), float(problem.y0[TH])
    far = math.radians(89.0)
    for term in problem.objective:
        if term.name == "max_final_latitude":
            return far, lon0
        if term.name == "min_final_latitude":
            return -far, lon0
        if term.name == "max_final_longitude":
            return lat0, lon0 + math.pi / 2
        if term.name == "min_final_longitude":
            return lat0, lon0 - math.pi / 2
    return None
