"""The verification's right-hand side compiled: the time-domain equations of motion under the
flown bank profile, for one state, in one numba call.

The integrator evaluates the right-hand side thousands of times per verification; in Python
(forces on numpy scalars, the bank profile looked up in Python) each call costs about 50 µs,
compiled about 1 µs plus the call. The equations are ``models.eom`` (paper 000 eq. 1, time
form, rotating planet), the forces ``bank_state_compiled.aero_terms`` (the compiled models:
exponential density, polynomial CL/CD, alpha on its schedule), the bank the profile of
``trajectory.bank_profile``: linear in time or in energy between the nodes, or the exact
integral of a first-order-hold bank rate. ``tests/unit/test_flown_rates.py`` holds it equal to
the Python form.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from worker.solver.models import eom
from worker.solver.models.bank_state_compiled import _KB, _OMEGA, aero_terms

Array = np.ndarray

LINEAR_IN_TIME, HOLD_IN_TIME, LINEAR_IN_ENERGY = 0, 1, 2
"""How the bank runs between the nodes: linear in time, integrated from a first-order-hold rate
(piecewise quadratic in time), or linear in the energy e = 1/r - V^2/2."""


@njit(cache=True, nogil=True, error_model="numpy")
def flown_bank(s: float, kind: int, grid: Array, bank: Array, rate: Array) -> float:
    """The bank at grid value ``s`` (time or energy), clamped to the grid's ends as
    ``np.interp`` does (``trajectory.bank_profile``)."""
    n = grid.size
    k = int(np.searchsorted(grid, s, side="right")) - 1
    k = min(max(k, 0), n - 2)
    h = grid[k + 1] - grid[k]
    if kind == HOLD_IN_TIME:
        dt = min(max(s - grid[k], 0.0), h)
        return float(bank[k] + rate[k] * dt + 0.5 * (rate[k + 1] - rate[k]) * dt * dt / h)
    frac = min(max((s - grid[k]) / h, 0.0), 1.0)
    return float(bank[k] + frac * (bank[k + 1] - bank[k]))


@njit(cache=True, nogil=True, error_model="numpy")
def point_time_rates(
    r: float, ph: float, v: float, ga: float, ps: float, u1: float, u2: float, p: Array
) -> tuple[tuple[float, float, float, float, float, float], float, float]:
    """The six time-form rates at one point under the lift direction (u1, u2) (its magnitude
    scales the lift), with the density and angle of attack there (for the running costs)."""
    rho, _rho_r, alpha, _alpha_v, cl, _dcl, cd, _dcd = aero_terms(r, v, p)
    qk = p[_KB] * rho * v * v
    k = eom.kinematics(r, ph, v, ga, ps, False)
    f = eom.rates(k, r, v, qk * cl, qk * cd, u1, u2, p[_OMEGA], False, True)
    return (f[0], f[1], f[2], f[3], f[4], f[5]), rho, alpha


@njit(cache=True, nogil=True, error_model="numpy")
def flown_rates(
    t: float, y: Array, kind: int, grid: Array, bank: Array, rate: Array, p: Array
) -> Array:
    """dy/dt for y = [r, theta, phi, V, gamma, psi] (nondimensional) at time ``t`` under the
    flown bank; ``p`` the compiled force parameters (``bank_state_compiled``)."""
    r, ph, v, ga, ps = y[0], y[2], y[3], y[4], y[5]
    s = 1.0 / r - 0.5 * v * v if kind == LINEAR_IN_ENERGY else t
    sigma = flown_bank(s, kind, grid, bank, rate)
    f, _rho, _alpha = point_time_rates(r, ph, v, ga, ps, math.cos(sigma), math.sin(sigma), p)
    out = np.empty(6)
    for i in range(6):
        out[i] = f[i]
    return out


def warm_up(p: Array) -> None:
    """Compile (or load) the kernel on a tiny case of each bank profile."""
    grid = np.array([0.0, 0.5, 1.0])
    bank = np.array([0.1, 0.2, 0.1])
    y = np.array([1.015, 0.0, 0.0, 0.9, 0.0, 0.0])
    for kind in (LINEAR_IN_TIME, HOLD_IN_TIME, LINEAR_IN_ENERGY):
        flown_rates(0.25, y, kind, grid, bank, bank, p)
