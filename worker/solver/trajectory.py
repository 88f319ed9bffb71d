"""The optimized trajectory every method hands on, and its control profile between the nodes.

A shared type at the bottom of the core: the methods produce it, verification propagates it and
the result writes it, so it imports nothing of the solver.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal, Protocol

import numpy as np

Array = np.ndarray
GridKind = Literal["energy", "time"]

TIME_STATE_NAMES = (
    "altitude_m",
    "longitude_deg",
    "latitude_deg",
    "velocity_m_s",
    "flight_path_angle_deg",
    "heading_deg",
)
"""The point-mass states y = [r, theta, phi, V, gamma, psi] by their SI names, in order: the
columns of ``OptimizedTrajectory.y`` and the states that can carry a terminal condition."""


class AttitudePath(Protocol):
    """Bank and angle of attack as continuous functions of time, as a method represents them
    between its nodes (e.g. a polynomial per mesh interval); times nondimensional from the
    start."""

    def at(self, t: Array) -> tuple[Array, Array]:
        """(bank in radians, angle of attack in degrees) at times ``t``."""
        ...

    def rates_at(self, t: Array) -> tuple[Array, Array]:
        """(d bank/dt, d alpha/dt) at times ``t``, radians per nondimensional time."""
        ...


@dataclass
class OptimizedTrajectory:
    """The optimizer's nodes in time-form states (nondimensional) with their grid and bank."""

    grid_kind: GridKind
    grid: Array  # (K,) energy or nondimensional time since the start
    y: Array  # (K, 6)
    t: Array  # (K,) nondimensional time since the start
    bank: Array  # (K,) radians
    alpha_deg: Array | None = None  # (K,) when alpha is a decision variable
    bank_rate: Array | None = None  # (K,) d(bank)/dt at the nodes (time grid), first-order hold
    attitude: AttitudePath | None = None
    """Bank and angle of attack between the nodes when the method represents them continuously
    (both states of its model): verification flies this path, not an interpolation of nodes."""


def bank_profile_at(traj: OptimizedTrajectory, s: Array) -> Array:
    """``bank_profile`` at many grid values at once (the same profile, vectorized)."""
    grid, bank = traj.grid, traj.bank
    s = np.asarray(s, dtype=float)
    if traj.attitude is not None:
        return traj.attitude.at(s)[0]
    if traj.bank_rate is None or traj.grid_kind != "time":
        return np.interp(s, grid, bank)
    return held_quadratic(grid, bank, traj.bank_rate, s)


def held_quadratic(grid: Array, values: Array, rates: Array, t: Array) -> Array:
    """An angle held by its rate, the rate linear between the nodes (first-order hold): the
    quadratic from each node's value at times ``t`` (clipped to the grid)."""
    k = np.clip(np.searchsorted(grid, t, side="right") - 1, 0, grid.size - 2)
    h = grid[k + 1] - grid[k]
    dt = np.clip(t - grid[k], 0.0, h)
    w0, w1 = rates[k], rates[k + 1]
    return np.asarray(values[k] + w0 * dt + 0.5 * (w1 - w0) * dt * dt / h)


def bank_rate_at(traj: OptimizedTrajectory, t: Array, bank: Array) -> Array:
    """The flown bank rate at nondimensional times ``t`` (``bank`` the flown bank there): the
    first-order-hold rate where the trajectory carries one, else the slope of ``bank``."""
    if traj.attitude is not None:
        return traj.attitude.rates_at(t)[0]
    if traj.bank_rate is not None and traj.grid_kind == "time":
        return np.interp(t, traj.grid, traj.bank_rate)
    return np.gradient(bank, t) if t.size > 1 else np.zeros_like(t)


def bank_profile(traj: OptimizedTrajectory, s: Any) -> float:
    """Bank angle at grid value ``s``: linear between nodes, or, with ``bank_rate`` on a time grid,
    the exact integral of the first-order-hold rate from the interval's node (piecewise quadratic).
    """
    grid, bank = traj.grid, traj.bank
    if traj.bank_rate is None or traj.grid_kind != "time":
        return float(np.interp(s, grid, bank))
    k = int(np.clip(np.searchsorted(grid, s, side="right") - 1, 0, grid.size - 2))
    h = float(grid[k + 1] - grid[k])
    dt = float(np.clip(s - grid[k], 0.0, h))
    w0, w1 = float(traj.bank_rate[k]), float(traj.bank_rate[k + 1])
    return float(bank[k] + w0 * dt + 0.5 * (w1 - w0) * dt * dt / h)


class PhaseControls(Protocol):
    """A phased method's controls between its nodes, as it represents them (e.g. a polynomial
    per collocation segment), within the phase's control bounds."""

    def at(self, phase: int, t: Array) -> Array:
        """(len(t), n_controls) controls of ``phase`` at nondimensional times ``t`` (from the
        flight's start): [alpha rad, bank rad] and, with propulsion, the commanded thrust."""
        ...

    def breaks(self, phase: int) -> Array:
        """Times (nondimensional, from the flight's start) where ``phase``'s control pieces
        meet, its start and end included: a propagation restarts there."""
        ...


@dataclass
class PhasedTrajectory:
    """The nodes of a flight in phases (paper 004), concatenated in time: a phase's last node
    and the next phase's first node are both kept (same time, the controls may jump).

    States are nondimensional (``units.Scales``): [r, theta, phi, V, gamma, psi], then the mass
    relative to the initial mass and, when the thrust lags, the thrust in m0 g0. Controls are
    [alpha rad, bank rad] and, with propulsion, the commanded thrust in m0 g0.
    """

    t: Array  # (K,) nondimensional time since the start
    x: Array  # (K, n_states)
    u: Array  # (K, n_controls)
    phase: Array  # (K,) phase index of each node
    bounds: list[tuple[float, float]]  # (start, end) time of each phase, nondimensional
    controls: PhaseControls
