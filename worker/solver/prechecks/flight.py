"""Flights of simple control laws from the entry point, through the solver's own dynamics.

A flight holds one bank angle from the entry state to the end of the problem's flight (its
terminal altitude, its final energy, the ground or a time cap) and samples heat rate, dynamic
pressure and load factor along it. The right-hand side is the verification's: the compiled
kernel (``models.flown_rates``) for the compiled force models with a scheduled angle of attack,
the scalar Python form for any other scheduled vehicle, and the vectorized point-mass form for a
held lift control (an optimized angle of attack, a parabolic polar's normalized lift). These
flights cost milliseconds (tens of them on the tabulated US76 atmosphere): they are what the
pre-checks measure the problem against.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from worker.solver.models import flown_rates
from worker.solver.models.bank_state_compiled import compiled_parameters, float_arrays
from worker.solver.models.point_mass import time_dynamics
from worker.solver.models.scalar_rates import time_rates
from worker.solver.path_limits import path_values
from worker.solver.problem import EntryProblem

Array = np.ndarray

LONGEST_FLIGHT_S = 8000.0
"""Time cap of a flight with no fixed final time, s (entry flights last minutes, not hours)."""
SAMPLE_S = 0.5
"""Spacing of the samples a flight's peaks are read from, s (a heating peak's curvature spans
tens of seconds: the sampled peak is within 1e-4 of the continuous one)."""


@dataclass(frozen=True)
class Attitude:
    """What a flight holds besides its bank: ``value`` None flies the vehicle's angle-of-attack
    schedule; else the value held in the angle of attack's place (degrees, or a parabolic
    polar's normalized lift), ``note`` says why that value."""

    value: float | None
    note: str


@dataclass
class Flight:
    """A propagated flight on a uniform sample: time (s), nondimensional states (6, M), the path
    quantities (SI) and how it ended."""

    bank_deg: float
    t_s: Array
    y: Array
    heat_rate_W_m2: Array
    dynamic_pressure_Pa: Array
    load_factor_g: Array
    ended: str
    """"altitude" (the terminal altitude), "energy" (the final energy), "ground", "time"."""

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1])


ATTITUDE_CANDIDATES = 5
"""Held attitudes a vehicle without a schedule is flown at (evenly over its bounds)."""


def lift_up_attitudes(problem: EntryProblem) -> list[Attitude]:
    """The attitudes a least-bank flight is tried with: the schedule when the vehicle has one;
    else a few held values evenly over the bounds of an optimized angle of attack (or of a
    parabolic polar's normalized lift), of which the caller keeps the one whose first pull-up
    peaks lowest. A held attitude also sets the drag, and the best attitude varies along a
    flight, so no theorem makes the lowest of them the least any flight reaches: it names a
    likely cause, never a proof."""
    if problem.lift_range is not None:
        lo, hi = problem.lift_range
        what = "normalized lift"
        values = np.linspace(max(lo, 0.05 * hi), hi, ATTITUDE_CANDIDATES)
    elif problem.alpha_optimized and problem.alpha_range is not None:
        lo, hi = (math.degrees(a) for a in problem.alpha_range)
        what = "angle of attack"
        values = np.linspace(lo, hi, ATTITUDE_CANDIDATES)
    else:
        return [Attitude(None, "the angle-of-attack schedule")]
    shown = ", ".join(f"{v:.3g}" for v in values)
    return [
        Attitude(
            float(v),
            f"the {what} held at {v:.3g} (of {shown} tried, its first pull-up peaks lowest)",
        )
        for v in values
    ]


def least_bank(problem: EntryProblem) -> float:
    """The bank (rad) of the most upward lift the control limits allow: 0 when the range holds
    it, else its bound nearest 0."""
    return min(max(0.0, problem.bank_min), problem.bank_max)


def _rhs(problem: EntryProblem, bank: float, attitude: Attitude) -> Callable[[float, Array], Array]:
    """dy/dt under a constant bank and ``attitude``: compiled where the models allow it."""
    forces, omega = problem.forces, problem.omega
    cos_b, sin_b = math.cos(bank), math.sin(bank)
    if attitude.value is None:
        params = compiled_parameters(forces, omega)
        if params is not None:
            grid, banks, rates = float_arrays(np.array([0.0, 1.0]), np.full(2, bank), np.zeros(2))
            kernel = flown_rates.flown_rates
            kind = flown_rates.LINEAR_IN_TIME

            def compiled(t: float, y: Array) -> Array:
                return kernel(t, y, kind, grid, banks, rates, params)

            return compiled

        def scalar(t: float, y: Array) -> Array:
            _, lift, drag, _ = forces.lift_drag(y[0], y[3])
            return time_rates(y, cos_b, sin_b, float(lift), float(drag), omega)

        return scalar
    u = np.array([[cos_b, sin_b]])
    held = np.array([attitude.value])

    def vectorized(t: float, y: Array) -> Array:
        return time_dynamics(y[None, :], u, forces, omega, held, jacobians=False).f[0]

    return vectorized


def _events(problem: EntryProblem) -> tuple[list[Any], list[str]]:
    """The events that end a flight where the problem's flight ends, and their names."""
    terminal = problem.terminal.get("altitude_m")
    end_h = terminal.target() if terminal is not None else None
    if terminal is not None and terminal.kind == "range" and terminal.lo is not None:
        end_h = terminal.lo  # the lowest the flight may end
    r_end = end_h if end_h is not None and end_h > 1.0 else 1.0
    names: list[str] = []
    events: list[Any] = []

    def altitude(t: float, y: Array) -> float:
        return float(y[0] - r_end)

    altitude.terminal = True  # type: ignore[attr-defined]
    altitude.direction = -1.0  # type: ignore[attr-defined]
    events.append(altitude)
    names.append("altitude" if r_end > 1.0 else "ground")
    if problem.energy_final is not None:
        e_final = float(problem.energy_final)

        def energy(t: float, y: Array) -> float:
            return float(1.0 / y[0] - 0.5 * y[3] * y[3] - e_final)

        energy.terminal = True  # type: ignore[attr-defined]
        energy.direction = 1.0  # type: ignore[attr-defined]
        events.append(energy)
        names.append("energy")
    return events, names


def fly(
    problem: EntryProblem,
    bank: float,
    attitude: Attitude | None = None,
    *,
    rtol: float = 1e-8,
    until_s: float | None = None,
) -> Flight:
    """Fly ``bank`` (rad) held from the entry state with ``attitude`` (default: the schedule)
    until the problem's flight ends (terminal altitude, final energy, ground), its fixed final
    time or ``until_s`` (s), whichever comes first."""
    attitude = attitude or Attitude(None, "the angle-of-attack schedule")
    ts = problem.scales.time_s
    cap_s = until_s if until_s is not None else LONGEST_FLIGHT_S
    if problem.final_time is not None:
        cap_s = min(cap_s, problem.final_time * ts)
    events, names = _events(problem)
    solution = solve_ivp(
        _rhs(problem, bank, attitude), (0.0, cap_s / ts), np.asarray(problem.y0, dtype=float),
        method="DOP853", rtol=rtol, atol=rtol * 1e-2, events=events, dense_output=True,
    )  # fmt: skip
    ended = "time"
    if solution.status == 1:
        fired = [i for i, hits in enumerate(solution.t_events) if len(hits)]
        ended = names[fired[0]] if fired else "time"
    end = float(solution.t[-1])
    count = max(math.ceil(end * ts / SAMPLE_S), 1) + 1
    t = np.linspace(0.0, end, count)
    y = solution.sol(t)
    held = None if attitude.value is None else np.full(t.size, attitude.value)
    terms = problem.forces.terms(y[0], y[3], held)
    values = path_values(problem.forces, problem.heat_model, y[0], y[3], terms)
    return Flight(
        bank_deg=math.degrees(bank),
        t_s=t * ts,
        y=y,
        heat_rate_W_m2=np.asarray(values.heat_rate),
        dynamic_pressure_Pa=np.asarray(values.dynamic_pressure),
        load_factor_g=np.asarray(values.load_factor),
        ended=ended,
    )
