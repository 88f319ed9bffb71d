"""Time-domain entry dynamics with angle of attack and bank as states, their rates as controls.

State z = [r, theta, phi, V, gamma, psi, sigma, alpha] (``layout.ALPHA_BANK_STATE``; alpha in
radians like every angle state), control w = [d sigma / dt, d alpha / dt] (the Shuttle problems,
paper 003). The point-mass part is ``models.point_mass.time_dynamics`` (``models.eom``) with the
lift scaled by u = (cos sigma, sin sigma) and the forces evaluated at the state's alpha: CL(alpha),
CD(alpha) and their slopes from the aerodynamic model, no alpha schedule. Time-dilated on a
normalized interval of length s like the bank-state model: F = s f(z, w) (paper 002 eq. 10), A =
dF/dz = s df/dz (8 x 8), B = dF/dw = s df/dw (8 x 2), S = dF/ds = f (eq. 14). Vectorized over nodes
and complex-safe (complex-step tests) when the force models are."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from worker.solver.forces import ForceTerms, VehicleForces
from worker.solver.models.layout import ALPHA_BANK_STATE
from worker.solver.models.point_mass import GA, PS, V, time_dynamics

Array = np.ndarray

_N = ALPHA_BANK_STATE.size
_POINT = ALPHA_BANK_STATE.index("bank_deg")  # the point-mass states come first
SIGMA = ALPHA_BANK_STATE.index("bank_deg")
ALPHA = ALPHA_BANK_STATE.index("angle_of_attack_deg")
_DEG_PER_RAD = 180.0 / math.pi  # the aerodynamic models take alpha in degrees


@dataclass
class AlphaBankStateDerivatives:
    """F = s f(z, w) and its Jacobians A (N, 8, 8), B (N, 8, 2), S = f (N, 8) at N points."""

    F: Array  # (N, 8)
    A: Array | None  # (N, 8, 8)
    B: Array | None  # (N, 8, 2): dF/dw for w = (bank rate, alpha rate)
    S: Array  # (N, 8): dF/ds = f
    forces: ForceTerms


def alpha_bank_state_dynamics(
    z: Array,
    w: Array,
    forces: VehicleForces,
    omega: float,
    s: Array | float = 1.0,
    *,
    jacobians: bool = True,
    unit: float = _DEG_PER_RAD,
) -> AlphaBankStateDerivatives:
    """Time-dilated dynamics F = s f(z, w) with analytic Jacobians (paper 002 eq. 10, 14).

    ``z`` is (N, 8), ``w`` (N, 2) the bank and alpha rates, ``s`` the interval length(s)
    (scalar or (N,)); with ``s = 1`` this is plain dz/dt. ``unit``: the aerodynamic model's
    argument per unit of the last state (degrees per radian; 1 for a polar's normalized lift,
    which the models take in alpha's place).
    """
    sigma = z[:, SIGMA]
    alpha_deg = z[:, ALPHA] * unit
    cs, sn = np.cos(sigma), np.sin(sigma)
    u = np.column_stack([cs, sn])
    td = time_dynamics(z[:, :_POINT], u, forces, omega, alpha_deg, jacobians=jacobians)
    n = z.shape[0]
    f = np.empty((n, _N), dtype=np.result_type(td.f, w))
    f[:, :_POINT] = td.f
    f[:, SIGMA] = w[:, 0]
    f[:, ALPHA] = w[:, 1]
    s_col = np.asarray(s)
    s_vec = s_col[:, None] if s_col.ndim == 1 else s_col
    if not jacobians:
        return AlphaBankStateDerivatives(F=s_vec * f, A=None, B=None, S=f, forces=td.forces)
    assert td.A is not None and td.B is not None
    ft = td.forces
    A = np.zeros((n, _N, _N), dtype=np.result_type(td.A, s_col))
    A[:, :_POINT, :_POINT] = td.A
    # d f / d sigma = B_u (d u / d sigma) with d u / d sigma = (-sin sigma, cos sigma)
    A[:, :_POINT, SIGMA] = td.B[:, :, 0] * (-sn)[:, None] + td.B[:, :, 1] * cs[:, None]
    # d f / d alpha: only the lift and the drag depend on alpha (V', gamma', psi' of eom.rates)
    A[:, V, ALPHA] = -ft.drag_a * unit
    A[:, GA, ALPHA] = ft.lift_a * u[:, 0] / z[:, V] * unit
    A[:, PS, ALPHA] = ft.lift_a * u[:, 1] / (z[:, V] * np.cos(z[:, GA])) * unit
    s_mat = s_col[:, None, None] if s_col.ndim == 1 else s_col
    A *= s_mat
    B = np.zeros((n, _N, 2), dtype=A.dtype)
    B[:, SIGMA, 0] = s_col
    B[:, ALPHA, 1] = s_col
    return AlphaBankStateDerivatives(F=s_vec * f, A=A, B=B, S=f, forces=ft)


__all__ = ["ALPHA", "SIGMA", "AlphaBankStateDerivatives", "alpha_bank_state_dynamics"]
