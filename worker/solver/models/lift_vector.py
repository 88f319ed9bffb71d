"""Entry dynamics with the lift vector as the control: u = (lam cos sigma, lam sin sigma, lam^2).

Paper 001 (eqs. 8-10): with a parabolic polar CL = lam CL*, CD = cd0 + k CL^2 the equations of
motion are affine in u, the lift's two components entering through u1 and u2 and the induced
drag through u3; the nonconvex u3 = u1^2 + u2^2 is relaxed to u1^2 + u2^2 <= u3 (eq. 34) by the
method. A vehicle whose angle of attack follows a schedule (any aerodynamic model) flies the same
way with lam the share of the schedule's lift it uses (lam = 1 when flown): its lift and drag are
those of the scheduled angle of attack and u3 moves nothing. Two planet models, both on the
state y = [r, theta, phi, V, gamma, psi] (nondimensional, heading clockwise from north):

- ``spherical``: the point-mass equations every method uses (``models.point_mass`` /
  ``models.eom``, rotation included), evaluated with the lam = 1 forces and u in the place of
  (cos sigma, sin sigma); the induced drag of u3 - 1 is added to V'.
- ``flat``: paper 001 eq. 1 (Jorris & Cobb's flat-Earth, small flight-path-angle model):
  longitude and latitude are flat map coordinates in planet radii, r' = V gamma,
  theta' = V sin psi, phi' = V cos psi, V' = -D (no gravity), gamma' = (L cos sigma - 1)/V + V,
  psi' = L sin sigma / V. The paper's heading from east towards north is 90 deg - psi and its
  bank the negative of this one (a positive bank turns right here, as on the sphere).

Vectorized over nodes, with analytic Jacobians A = df/dy (N, 6, 6) and B = df/du (N, 6, 3).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from worker.solver.aero_models import ParabolicPolarAero
from worker.solver.forces import ForceTerms, VehicleForces
from worker.solver.models.point_mass import GA, PH, PS, TH, R, V, time_dynamics

Array = np.ndarray
PlanetModel = Literal["spherical", "flat"]


@dataclass
class LiftVectorDerivatives:
    """dy/dt and its Jacobians at N points, and the lam = 1 force terms used."""

    f: Array  # (N, 6)
    A: Array | None  # (N, 6, 6)
    B: Array | None  # (N, 6, 3)
    forces: ForceTerms


def polar_of(forces: VehicleForces) -> ParabolicPolarAero | None:
    """The vehicle's parabolic polar, or None when its angle of attack follows a schedule
    (TypeError for a vehicle with neither: an optimized angle of attack)."""
    aero = forces.aero
    if isinstance(aero, ParabolicPolarAero):
        return aero
    if forces.alpha_schedule is None:
        raise TypeError(
            f"the lift-vector model needs a parabolic polar or a scheduled angle of attack, not "
            f"{type(aero).__name__} with an optimized one"
        )
    return None


def lift_basis(forces: VehicleForces, n: int) -> tuple[Array | None, float]:
    """What the force models are evaluated at for the lam = 1 forces, and the induced drag per
    unit lift and unit u3: a polar's (ones in alpha's place, k CL*), a schedule's (None: the
    schedule's alpha, 0: its drag does not depend on u)."""
    polar = polar_of(forces)
    if polar is None:
        return None, 0.0
    return np.ones(n), polar.k_induced * polar.cl_star


def lift_vector_dynamics(
    y: Array,
    u: Array,
    forces: VehicleForces,
    omega: float,
    model: PlanetModel = "spherical",
    *,
    jacobians: bool = True,
) -> LiftVectorDerivatives:
    """dy/dt = f(y, u) for ``u`` (N, 3) = (u1, u2, u3), with A = df/dy and B = df/du."""
    n = y.shape[0]
    basis, k_cl = lift_basis(forces, n)
    if model == "spherical":
        td = time_dynamics(y, u[:, :2], forces, omega, basis, jacobians=jacobians)
        ft = td.forces
        excess = u[:, 2] - 1.0
        f = td.f.copy()
        f[:, V] -= k_cl * ft.lift * excess
        if not jacobians:
            return LiftVectorDerivatives(f, None, None, ft)
        assert td.A is not None and td.B is not None
        A = td.A.copy()
        A[:, V, R] -= k_cl * ft.lift_r * excess
        A[:, V, V] -= k_cl * ft.lift_v * excess
        B = np.zeros((n, 6, 3), dtype=f.dtype)
        B[:, :, :2] = td.B
        B[:, V, 2] = -k_cl * ft.lift
        return LiftVectorDerivatives(f, A, B, ft)
    if model != "flat":
        raise ValueError(f"unknown planet model {model!r}; expected 'spherical' or 'flat'")
    return _flat(y, u, forces, basis, k_cl, jacobians)


def _flat(
    y: Array, u: Array, forces: VehicleForces, basis: Array | None, k_cl: float, jacobians: bool
) -> LiftVectorDerivatives:
    """Paper 001 eq. 1 on this module's state (see the module docstring)."""
    r, v, ga, ps = y[:, R], y[:, V], y[:, GA], y[:, PS]
    u1, u2, u3 = u[:, 0], u[:, 1], u[:, 2]
    ft = forces.terms(r, v, basis)
    lift, drag = ft.lift, ft.drag + k_cl * ft.lift * (u3 - 1.0)
    sp, cp = np.sin(ps), np.cos(ps)
    f = np.empty((y.shape[0], 6), dtype=np.result_type(y, u, lift))
    f[:, R] = v * ga
    f[:, TH] = v * sp
    f[:, PH] = v * cp
    f[:, V] = -drag
    f[:, GA] = (lift * u1 - 1.0) / v + v
    f[:, PS] = lift * u2 / v
    if not jacobians:
        return LiftVectorDerivatives(f, None, None, ft)
    n = y.shape[0]
    A = np.zeros((n, 6, 6), dtype=f.dtype)
    A[:, R, V], A[:, R, GA] = ga, v
    A[:, TH, V], A[:, TH, PS] = sp, v * cp
    A[:, PH, V], A[:, PH, PS] = cp, -v * sp
    A[:, V, R] = -(ft.drag_r + k_cl * ft.lift_r * (u3 - 1.0))
    A[:, V, V] = -(ft.drag_v + k_cl * ft.lift_v * (u3 - 1.0))
    A[:, GA, R] = ft.lift_r * u1 / v
    A[:, GA, V] = ft.lift_v * u1 / v - (lift * u1 - 1.0) / (v * v) + 1.0
    A[:, PS, R] = ft.lift_r * u2 / v
    A[:, PS, V] = ft.lift_v * u2 / v - lift * u2 / (v * v)
    B = np.zeros((n, 6, 3), dtype=f.dtype)
    B[:, GA, 0] = lift / v
    B[:, PS, 1] = lift / v
    B[:, V, 2] = -k_cl * lift
    return LiftVectorDerivatives(f, A, B, ft)


def lift_controls(lam: Array, bank: Array) -> Array:
    """u = (lam cos sigma, lam sin sigma, lam^2) of normalized lift and bank, (N, 3)."""
    return np.column_stack([lam * np.cos(bank), lam * np.sin(bank), lam * lam])
