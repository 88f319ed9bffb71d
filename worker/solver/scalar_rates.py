"""The time-domain equations of motion for ONE state, in plain floats, for the integrator.

``dynamics.time_dynamics`` is vectorized over nodes and carries Jacobians; called with a single
state by an adaptive integrator (tens of thousands of calls per verification) its numpy
overhead dominates. This is the same right-hand side (paper 000 eq. 1 in time form) evaluated
with the ``math`` module; tests hold it equal to ``time_dynamics`` to round-off.
"""

from __future__ import annotations

import math

import numpy as np


def time_rates(y: np.ndarray, cos_bank: float, sin_bank: float, lift: float, drag: float,
               omega: float) -> np.ndarray:  # fmt: skip
    """dy/dt for y = [r, theta, phi, V, gamma, psi] with lift and drag already evaluated (g0)."""
    r, _, ph, v, ga, ps = (float(c) for c in y)
    sg, cg = math.sin(ga), math.cos(ga)
    sp, cp = math.sin(ps), math.cos(ps)
    sf, cf = math.sin(ph), math.cos(ph)
    out = np.empty(6)
    out[0] = v * sg
    out[1] = v * cg * sp / (r * cf)
    out[2] = v * cg * cp / r
    out[3] = -drag - sg / (r * r)
    out[4] = lift * cos_bank / v + (v - 1.0 / (r * v)) * cg / r
    out[5] = lift * sin_bank / (v * cg) + v * cg * sp * (sf / cf) / r
    if omega != 0.0:
        w2 = omega * omega
        out[3] += w2 * r * cf * (sg * cf - cg * sf * cp)
        out[4] += 2.0 * omega * cf * sp + w2 * r * cf * (cg * cf + sg * cp * sf) / v
        out[5] += -2.0 * omega * (sg / cg * cp * cf - sf) + w2 * r * sp * sf * cf / (v * cg)
    return out
