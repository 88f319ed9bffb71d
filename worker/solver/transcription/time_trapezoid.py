"""Trapezoidal discretization of the bank-state dynamics in time (comparison for paper 002 Table 4).

z_{k+1} - z_k = s_k / 2 (f(z_k, w_k) + f(z_{k+1}, w_{k+1})), linearized about the reference, in the
same ``IntervalMaps`` form as the exact FOH maps (with E = I - s/2 A_{k+1}), so one subproblem
builder serves both. Unlike the exact FOH maps, this is only second-order accurate in s: the
paper's "SCP3" needs 200-400 nodes for the accuracy the exact maps reach with 40.
"""

from __future__ import annotations

import numpy as np

from worker.solver.forces import VehicleForces
from worker.solver.models.bank_state import bank_state_dynamics
from worker.solver.transcription.foh_exact import IntervalMaps

Array = np.ndarray


def trapezoid_maps(
    z: Array, w: Array, s: Array, forces: VehicleForces, omega: float
) -> IntervalMaps:
    """Linearized trapezoidal maps about nodes ``z`` (K, 7), rates ``w`` (K,), lengths ``s``."""
    d = bank_state_dynamics(z, w, forces, omega)
    assert d.A is not None and d.B is not None
    half = 0.5 * s
    eye = np.eye(z.shape[1])[None, :, :]
    f_mean = 0.5 * (d.S[:-1] + d.S[1:])
    return IntervalMaps(
        Phi=eye + half[:, None, None] * d.A[:-1],
        Bm=half[:, None] * d.B[:-1],
        Bp=half[:, None] * d.B[1:],
        S=f_mean,
        x_prop=z[:-1] + s[:, None] * f_mean,
        E=eye - half[:, None, None] * d.A[1:],
    )
