"""The least-bank flight's first pull-up and its path peaks.

Flown with the most upward lift the control limits allow (bank 0, or the bound nearest it) from
the entry point, a vehicle dives into the atmosphere until its lift turns the flight path up:
the heat rate, dynamic pressure and load factor peak during that first pull-up. With the angle
of attack on a schedule the bank only turns the lift, and rolling it away from vertical lets the
vehicle sink deeper at the same speed: no bank profile was found to fly the first pull-up with a
lower peak (measured against an NLP that minimizes the peak over every bank profile,
docs/problem-contract.md, "Pre-checks"). A limit below that peak cannot be held.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from worker.solver.prechecks.flight import (
    LONGEST_FLIGHT_S,
    Attitude,
    Flight,
    fly,
    least_bank,
    lift_up_attitudes,
)
from worker.solver.problem import EntryProblem

Array = np.ndarray

PEAK_QUANTITIES = ("heat_rate_W_m2", "dynamic_pressure_Pa", "load_factor_g")


@dataclass(frozen=True)
class Peak:
    """A path quantity's largest value over the first pull-up, when and where."""

    value: float
    time_s: float
    altitude_m: float
    velocity_m_s: float


@dataclass
class PullUp:
    """The least-bank flight, its attitude, where its first pull-up ends and its peaks there."""

    flight: Flight
    attitude: Attitude
    end_index: int
    peaks: dict[str, Peak]

    @property
    def end_s(self) -> float:
        return float(self.flight.t_s[self.end_index])


def _first_local_max(values: Array, start: int = 0) -> int | None:
    """Index of the first strict local maximum of ``values`` at or after ``start``."""
    rising = np.diff(values[start:]) > 0.0
    turns = np.flatnonzero(rising[:-1] & ~rising[1:])
    return start + int(turns[0]) + 1 if turns.size else None


def _first_local_min(values: Array) -> int | None:
    """Index of the first strict local minimum of ``values``."""
    falling = np.diff(values) < 0.0
    turns = np.flatnonzero(falling[:-1] & ~falling[1:])
    return int(turns[0]) + 1 if turns.size else None


def pull_up_end(flight: Flight) -> int:
    """The sample where the first pull-up ends: the flight-path angle's first maximum after its
    first minimum (a flight that starts climbing counts from its start), extended to the heat
    rate's first maximum when that comes later; the flight's end when it has none."""
    gamma = flight.y[4]
    last = gamma.size - 1
    low = _first_local_min(gamma)
    top = _first_local_max(gamma, low if low is not None else 0)
    end = top if top is not None else last
    heat = _first_local_max(flight.heat_rate_W_m2)
    if heat is not None and heat > end:
        end = heat
    return end


FIRST_HORIZON_S = 600.0
"""How long the first try flies (s): a first pull-up is over within minutes; a flight whose
pull-up has not ended by then is flown twice as long, and so on."""
RTOL = 1e-7
"""The flights' relative tolerance: the peaks move by less than 1e-6 from 1e-8's."""


def _pull_up(problem: EntryProblem, attitude: Attitude) -> PullUp:
    """The least-bank flight with ``attitude`` flown until its first pull-up is over."""
    horizon = FIRST_HORIZON_S
    while True:
        flight = fly(problem, least_bank(problem), attitude, rtol=RTOL, until_s=horizon)
        end = pull_up_end(flight)
        cut_short = flight.ended == "time" and flight.duration_s >= horizon * (1.0 - 1e-9)
        if end < flight.t_s.size - 1 or not cut_short or horizon >= LONGEST_FLIGHT_S:
            break
        horizon = min(2.0 * horizon, LONGEST_FLIGHT_S)
    peaks = {}
    radius = problem.scales.radius_m
    speed = problem.scales.speed_m_s
    for name in PEAK_QUANTITIES:
        values = getattr(flight, name)[: end + 1]
        k = int(np.argmax(values))
        peaks[name] = Peak(
            value=float(values[k]),
            time_s=float(flight.t_s[k]),
            altitude_m=float((flight.y[0, k] - 1.0) * radius),
            velocity_m_s=float(flight.y[3, k] * speed),
        )
    return PullUp(flight=flight, attitude=attitude, end_index=end, peaks=peaks)


def _worst_ratio(problem: EntryProblem, pull_up: PullUp) -> float:
    """The largest peak / limit over the problem's path limits (the heat peak without any)."""
    limits = problem.limits
    pairs = [
        ("heat_rate_W_m2", limits.heat_max_W_m2),
        ("dynamic_pressure_Pa", limits.dynamic_pressure_max_Pa),
        ("load_factor_g", limits.load_factor_max_g),
    ]
    ratios = [pull_up.peaks[name].value / limit for name, limit in pairs if limit]
    return max(ratios) if ratios else pull_up.peaks["heat_rate_W_m2"].value


def least_bank_pull_up(problem: EntryProblem) -> PullUp:
    """The least-bank flight's first pull-up: with the schedule, or with the held attitude of
    those tried whose peaks come lowest against the limits."""
    tried = [_pull_up(problem, attitude) for attitude in lift_up_attitudes(problem)]
    return min(tried, key=lambda pull_up: _worst_ratio(problem, pull_up))


def bank_text(problem: EntryProblem) -> str:
    """How the least-bank flight is named in a message: "full lift-up" at bank 0."""
    bank = math.degrees(least_bank(problem))
    return "full lift-up" if bank == 0.0 else f"the least bank the limits allow ({bank:g} deg)"
