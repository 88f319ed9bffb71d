"""The trapezoid's discretization error of the energy-domain dynamics, for a deferred correction.

Each interval is integrated from its node under the control the verification flies (the bank
angle linear in energy between the nodes, the control magnitude likewise), by classical RK4
on sub-steps; the exact increment minus the trapezoid's is the defect. Added to the
right-hand side of the trapezoidal rows linearized about the same reference, it makes the
SCP's fixed point satisfy the exact interval maps, so a coarse mesh converges to a
trajectory its own controls fly (defect correction: Pereyra, Numer. Math. 8 (1966); the same
idea as the exact first-order hold of paper 002, eq. 14, with the trapezoid's Jacobians).
The running costs (heat load, flight time) are integrated alongside.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from worker.solver.models.point_mass import EnergyRates

Array = np.ndarray
RatesFn = Callable[[Array, Array, Array], EnergyRates]
"""(x (M, nx), u (M, 2), e (M,)) -> the energy-form rates at those points."""
DensityFn = Callable[[Array, EnergyRates], Array]
"""(x (M, nx), rates) -> (M, m) running-cost densities per unit energy."""


@dataclass(frozen=True)
class IntervalIncrements:
    """What each interval adds when integrated exactly from its node."""

    state: Array  # (N, nx) x(e_{i+1}) - x_i
    running: Array  # (N, m) integral of each running-cost density over the interval


def interval_control(u_start: Array, u_end: Array, fraction: float) -> Array:
    """The control at ``fraction`` of each interval: bank angle and magnitude linear between the
    nodes' (as the verification interpolates the bank), not the chord between the vectors."""
    bank0 = np.arctan2(u_start[:, 1], u_start[:, 0])
    bank1 = np.arctan2(u_end[:, 1], u_end[:, 0])
    size0 = np.linalg.norm(u_start, axis=1)
    size1 = np.linalg.norm(u_end, axis=1)
    bank = bank0 + fraction * (bank1 - bank0)
    size = size0 + fraction * (size1 - size0)
    return np.column_stack([size * np.cos(bank), size * np.sin(bank)])


def exact_increments(
    e: Array,
    x: Array,
    u: Array,
    rates: RatesFn,
    densities: DensityFn,
    substeps: int,
) -> IntervalIncrements:
    """Integrate every interval of the grid ``e`` from its node ``x_i`` at once (vectorized over
    intervals), ``substeps`` RK4 steps each, under ``interval_control``."""
    h = np.diff(e)
    x0 = x[:-1]
    u0, u1 = u[:-1], u[1:]
    nx = x.shape[1]

    def rhs(state: Array, fraction: float) -> Array:
        """d/dtau of (x, running costs) with e = e_i + tau h_i."""
        xs = state[:, :nx]
        us = interval_control(u0, u1, fraction)
        r = rates(xs, us, e[:-1] + fraction * h)
        dens = densities(xs, r)
        return np.column_stack([r.f, dens]) * h[:, None]

    m = densities(x0, rates(x0, u0, e[:-1])).shape[1]
    state = np.column_stack([x0, np.zeros((x0.shape[0], m))])
    step = 1.0 / substeps
    for k in range(substeps):
        tau = k * step
        k1 = rhs(state, tau)
        k2 = rhs(state + 0.5 * step * k1, tau + 0.5 * step)
        k3 = rhs(state + 0.5 * step * k2, tau + 0.5 * step)
        k4 = rhs(state + step * k3, tau + step)
        state = state + (step / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return IntervalIncrements(state=state[:, :nx] - x0, running=state[:, nx:])


def trapezoid_defect(e: Array, x: Array, f: Array, increments: IntervalIncrements) -> Array:
    """(N, nx) exact increment minus the trapezoid's h/2 (f_i + f_{i+1}) at the same nodes."""
    h = np.diff(e)
    defect: Array = increments.state - 0.5 * h[:, None] * (f[:-1] + f[1:])
    return defect
