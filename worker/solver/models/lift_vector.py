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

from worker.solver.aero_models import LiftShareAero, ParabolicPolarAero
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


LiftLaw = Literal["polar", "share", "schedule"]
"""How a vehicle's lift vector sets its forces: a parabolic polar's normalized lift; the lift
share lam = CL(alpha, M) / CL(alpha_max, M) of an optimized angle of attack
(``aero_models.LiftShareAero``); or the share of a scheduled angle of attack's lift (u3 idle)."""

SHARE_FLOOR = 1.0e-3
"""Smallest lam the u3 partial of a lift-share vehicle's drag is taken at (it goes as 1/lam)."""


def lift_law(forces: VehicleForces) -> LiftLaw:
    """The vehicle's lift law (TypeError for an optimized angle of attack not given as a lift
    share)."""
    aero = forces.aero
    if isinstance(aero, ParabolicPolarAero):
        return "polar"
    if isinstance(aero, LiftShareAero):
        return "share"
    if forces.alpha_schedule is None:
        raise TypeError(
            f"the lift-vector model needs a parabolic polar, a lift share or a scheduled angle "
            f"of attack, not {type(aero).__name__} with an optimized one"
        )
    return "schedule"


def polar_of(forces: VehicleForces) -> ParabolicPolarAero | None:
    """The vehicle's parabolic polar, or None for another lift law."""
    return forces.aero if isinstance(forces.aero, ParabolicPolarAero) else None


def lift_basis(forces: VehicleForces, n: int) -> Array | None:
    """What the force models are evaluated at for the lam = 1 forces: ones in alpha's place (a
    polar's lam, a lift share), or None (the schedule's alpha)."""
    return None if lift_law(forces) == "schedule" else np.ones(n)


@dataclass
class DragOfU3:
    """The drag at u3 less the lam = 1 drag, its (r, V) partials, and the drag's u3 partial."""

    change: Array
    change_r: Array
    change_v: Array
    u3: Array


def drag_of_u3(forces: VehicleForces, y: Array, u3: Array, ft: ForceTerms) -> DragOfU3:
    """How u3 moves the drag: a polar's induced drag k CL* L (u3 - 1) (paper 001 eq. 10), a lift
    share's D(alpha(sqrt(u3))) - D(alpha_max), nothing for a schedule."""
    law = lift_law(forces)
    if law == "polar":
        polar = polar_of(forces)
        assert polar is not None
        k_cl = polar.k_induced * polar.cl_star  # induced drag per unit lift and unit u3
        excess = u3 - 1.0
        return DragOfU3(
            k_cl * ft.lift * excess, k_cl * ft.lift_r * excess, k_cl * ft.lift_v * excess,
            k_cl * ft.lift,
        )  # fmt: skip
    if law == "schedule":
        zero = np.zeros_like(u3)
        return DragOfU3(zero, zero, zero, zero)
    lam = np.sqrt(u3)
    fu = forces.terms(y[:, R], y[:, V], lam)
    safe = np.where(lam.real > SHARE_FLOOR, lam, SHARE_FLOOR)
    return DragOfU3(
        fu.drag - ft.drag, fu.drag_r - ft.drag_r, fu.drag_v - ft.drag_v, fu.drag_a / (2.0 * safe)
    )


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
    basis = lift_basis(forces, n)
    if model == "spherical":
        td = time_dynamics(y, u[:, :2], forces, omega, basis, jacobians=jacobians)
        ft = td.forces
        dd = drag_of_u3(forces, y, u[:, 2], ft)
        f = td.f.copy()
        f[:, V] -= dd.change
        if not jacobians:
            return LiftVectorDerivatives(f, None, None, ft)
        assert td.A is not None and td.B is not None
        A = td.A.copy()
        A[:, V, R] -= dd.change_r
        A[:, V, V] -= dd.change_v
        B = np.zeros((n, 6, 3), dtype=f.dtype)
        B[:, :, :2] = td.B
        B[:, V, 2] = -dd.u3
        return LiftVectorDerivatives(f, A, B, ft)
    if model != "flat":
        raise ValueError(f"unknown planet model {model!r}; expected 'spherical' or 'flat'")
    return _flat(y, u, forces, basis, jacobians)


def _flat(
    y: Array, u: Array, forces: VehicleForces, basis: Array | None, jacobians: bool
) -> LiftVectorDerivatives:
    """Paper 001 eq. 1 on this module's state (see the module docstring)."""
    r, v, ga, ps = y[:, R], y[:, V], y[:, GA], y[:, PS]
    u1, u2, u3 = u[:, 0], u[:, 1], u[:, 2]
    ft = forces.terms(r, v, basis)
    dd = drag_of_u3(forces, y, u3, ft)
    lift, drag = ft.lift, ft.drag + dd.change
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
    A[:, V, R] = -(ft.drag_r + dd.change_r)
    A[:, V, V] = -(ft.drag_v + dd.change_v)
    A[:, GA, R] = ft.lift_r * u1 / v
    A[:, GA, V] = ft.lift_v * u1 / v - (lift * u1 - 1.0) / (v * v) + 1.0
    A[:, PS, R] = ft.lift_r * u2 / v
    A[:, PS, V] = ft.lift_v * u2 / v - lift * u2 / (v * v)
    B = np.zeros((n, 6, 3), dtype=f.dtype)
    B[:, GA, 0] = lift / v
    B[:, PS, 1] = lift / v
    B[:, V, 2] = -dd.u3
    return LiftVectorDerivatives(f, A, B, ft)


def glide_share(forces: VehicleForces) -> float:
    """The lam a start's glide flies: 1 (a polar's best lift-to-drag ratio, a schedule's lift),
    or a lift share's best lift-to-drag ratio."""
    aero = forces.aero
    return aero.best_share if isinstance(aero, LiftShareAero) else 1.0


def lift_controls(lam: Array, bank: Array) -> Array:
    """u = (lam cos sigma, lam sin sigma, lam^2) of normalized lift and bank, (N, 3)."""
    return np.column_stack([lam * np.cos(bank), lam * np.sin(bank), lam * lam])
