"""The time-domain equations of motion for ONE state, in plain floats, for the integrator.

``models.point_mass.time_dynamics`` is vectorized over nodes and carries Jacobians; called with a
single state by an adaptive integrator (tens of thousands of calls per verification) its numpy
overhead dominates. This is ``models.eom`` (paper 000 eq. 1 in time form) compiled by numba for
floats, in the scalar form (divisions, each rate's rotation terms summed first); tests hold it
equal to ``time_dynamics`` to round-off.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from worker.solver.models import eom


@njit(cache=True, nogil=True, error_model="numpy")
def _rates(
    r: float, ph: float, v: float, ga: float, ps: float, u1: float, u2: float, lift: float,
    drag: float, omega: float,
) -> tuple[float, float, float, float, float, float]:  # fmt: skip
    """The six rates at one point (``models.eom.rates``, scalar form)."""
    k = eom.kinematics(r, ph, v, ga, ps, False)
    f = eom.rates(k, r, v, lift, drag, u1, u2, omega, False, True)
    return f[0], f[1], f[2], f[3], f[4], f[5]


def time_rates(y: np.ndarray, cos_bank: float, sin_bank: float, lift: float, drag: float,
               omega: float) -> np.ndarray:  # fmt: skip
    """dy/dt for y = [r, theta, phi, V, gamma, psi] with lift and drag already evaluated (g0)."""
    r, _, ph, v, ga, ps = (float(c) for c in y)
    return np.array(_rates(r, ph, v, ga, ps, cos_bank, sin_bank, lift, drag, float(omega)))
