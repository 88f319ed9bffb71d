"""Time-domain entry dynamics with the bank angle as a state and its rate as the control.

State z = [r, theta, phi, V, gamma, psi, sigma], control w = d(sigma)/dt (paper 002 sec. 2.2: bank
and bank rate bounded). Built on ``models.point_mass.time_dynamics`` with u = (cos sigma, sin
sigma), so the point-mass equations and their analytic Jacobians are not duplicated. The
time-dilated form on a normalized interval tau in [0, 1] of length s is F = s f(z, w) (paper 002 eq.
10), with A = dF/dz = s df/dz, B = dF/dw = s df/dw and S = dF/ds = f (eq. 14)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worker.solver.forces import ForceTerms, VehicleForces
from worker.solver.models.layout import BANK_STATE
from worker.solver.models.point_mass import time_dynamics

Array = np.ndarray

_N = BANK_STATE.size
SIGMA = BANK_STATE.index("bank_deg")  # the bank angle's index in z, after the point-mass states


@dataclass
class BankStateDerivatives:
    """F = s f(z, w) and its Jacobians A (N, 7, 7), B (N, 7), S = f (N, 7) at N points."""

    F: Array  # (N, 7)
    A: Array | None  # (N, 7, 7)
    B: Array | None  # (N, 7): dF/dw, one scalar control
    S: Array  # (N, 7): dF/ds = f
    forces: ForceTerms


def bank_state_dynamics(
    z: Array,
    w: Array,
    forces: VehicleForces,
    omega: float,
    s: Array | float = 1.0,
    *,
    jacobians: bool = True,
) -> BankStateDerivatives:
    """Time-dilated dynamics F = s f(z, w) with analytic Jacobians (paper 002 eq. 10, 14).

    ``z`` is (N, 7), ``w`` (N,) the bank rate, ``s`` the interval length(s) (scalar or (N,));
    with ``s = 1`` this is plain dz/dt. Complex-safe like ``time_dynamics``.
    """
    sigma = z[:, SIGMA]
    cs, sn = np.cos(sigma), np.sin(sigma)
    u = np.column_stack([cs, sn])
    td = time_dynamics(z[:, :SIGMA], u, forces, omega, jacobians=jacobians)
    n = z.shape[0]
    f = np.empty((n, _N), dtype=np.result_type(td.f, w))
    f[:, :SIGMA] = td.f
    f[:, SIGMA] = w
    s_col = np.asarray(s)
    s_vec = s_col[:, None] if s_col.ndim == 1 else s_col
    if not jacobians:
        return BankStateDerivatives(F=s_vec * f, A=None, B=None, S=f, forces=td.forces)
    assert td.A is not None and td.B is not None
    A = np.zeros((n, _N, _N), dtype=np.result_type(td.A, s_col))
    A[:, :SIGMA, :SIGMA] = td.A
    # d f / d sigma = B_u (d u / d sigma) with d u / d sigma = (-sin sigma, cos sigma)
    A[:, :SIGMA, SIGMA] = td.B[:, :, 0] * (-sn)[:, None] + td.B[:, :, 1] * cs[:, None]
    s_mat = s_col[:, None, None] if s_col.ndim == 1 else s_col
    A *= s_mat
    B = np.zeros((n, _N), dtype=A.dtype)
    B[:, SIGMA] = s_col
    return BankStateDerivatives(F=s_vec * f, A=A, B=B, S=f, forces=td.forces)
