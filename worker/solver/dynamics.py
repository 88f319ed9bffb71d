"""3-DoF point-mass entry dynamics over a spherical, optionally rotating planet.

Time form: state y = [r, theta, phi, V, gamma, psi] (radius, longitude, latitude, planet-relative
speed, flight-path angle, heading clockwise from north), control u = [cos(sigma), sin(sigma)]
scaling the lift (so a convex relaxation of u can be used, paper 000 eq. 20-22). Equations as in
paper 000 eq. 1 / Lu 2014 (time form), all nondimensional (units.Scales). Analytic Jacobians,
vectorized over nodes, complex-safe for complex-step tests.

Energy form: independent variable e = 1/r - V^2/2 (paper 000 eq. 7) and state
x = [r, theta, phi, gamma, psi], with the exact V = sqrt(2 (1/r - e)) (not the approximation of
eq. 8) and the exact de/dt = -r'/r^2 - V V' (equal to D V without rotation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worker.solver.forces import ForceTerms, VehicleForces

Array = np.ndarray

R, TH, PH, V, GA, PS = range(6)
N_TIME_STATES = 6
ENERGY_STATES = (R, TH, PH, GA, PS)  # which time-form states the energy form keeps


@dataclass
class TimeDerivatives:
    """dy/dt, its Jacobians in y and u, and the force terms used (for reuse by callers)."""

    f: Array  # (N, 6)
    A: Array | None  # (N, 6, 6); None when only values were asked for
    B: Array | None  # (N, 6, 2)
    forces: ForceTerms


def time_dynamics(
    y: Array,
    u: Array,
    forces: VehicleForces,
    omega: float,
    alpha_deg: Array | None = None,
    *,
    jacobians: bool = True,
) -> TimeDerivatives:
    """dy/dt = f(y, u) with analytic Jacobians A = df/dy, B = df/du (nondimensional).

    ``y`` is (N, 6), ``u`` is (N, 2) = (cos sigma, sin sigma) possibly inside the unit disc,
    ``omega`` the nondimensional rotation rate (0 for a non-rotating planet).
    """
    r, v, ga, ps, ph = y[:, R], y[:, V], y[:, GA], y[:, PS], y[:, PH]
    u1, u2 = u[:, 0], u[:, 1]
    ft = forces.terms(r, v, alpha_deg)
    L, D = ft.lift, ft.drag
    sg, cg, sp, cp, sf, cf = np.sin(ga), np.cos(ga), np.sin(ps), np.cos(ps), np.sin(ph), np.cos(ph)
    tf = sf / cf
    tg = sg / cg
    w2 = omega * omega
    n = y.shape[0]
    f = np.empty((n, 6), dtype=np.result_type(y, u, L))
    wv = sg * cf - cg * sf * cp
    gg = cg * cf + sg * cp * sf
    rot2 = w2 * r * sp * sf * cf / (v * cg)
    f_th = v * cg * sp / (r * cf)
    f_ph = v * cg * cp / r
    f[:, R] = v * sg  # r' = V sin(gamma)
    f[:, TH] = f_th  # theta' = V cos(gamma) sin(psi) / (r cos(phi))
    f[:, PH] = f_ph  # phi' = V cos(gamma) cos(psi) / r
    # V' = -D - sin(gamma)/r^2 + W^2 r cos(phi) (sin(gamma) cos(phi) - cos(gamma) sin(phi) cos(psi))
    f[:, V] = -D - sg / r**2 + w2 * r * cf * wv
    # gamma' = L u1 / V + (V - 1/(r V)) cos(gamma)/r + 2 W cos(phi) sin(psi)
    #          + W^2 r cos(phi) (cos(gamma) cos(phi) + sin(gamma) cos(psi) sin(phi)) / V
    f[:, GA] = (
        L * u1 / v + (v - 1.0 / (r * v)) * cg / r + 2.0 * omega * cf * sp + w2 * r * cf * gg / v
    )
    # psi' = L u2 / (V cos(gamma)) + V cos(gamma) sin(psi) tan(phi) / r
    #        - 2 W (tan(gamma) cos(psi) cos(phi) - sin(phi))
    #        + W^2 r sin(psi) sin(phi) cos(phi) / (V cos(gamma))
    f[:, PS] = L * u2 / (v * cg) + v * cg * sp * tf / r - 2.0 * omega * (tg * cp * cf - sf) + rot2
    if not jacobians:
        return TimeDerivatives(f=f, A=None, B=None, forces=ft)
    A = np.zeros((n, 6, 6), dtype=f.dtype)
    B = np.zeros((n, 6, 2), dtype=f.dtype)
    A[:, R, V] = sg
    A[:, R, GA] = v * cg
    A[:, TH, R] = -f_th / r
    A[:, TH, PH] = f_th * tf
    A[:, TH, V] = cg * sp / (r * cf)
    A[:, TH, GA] = -v * sg * sp / (r * cf)
    A[:, TH, PS] = v * cg * cp / (r * cf)
    A[:, PH, R] = -f_ph / r
    A[:, PH, V] = cg * cp / r
    A[:, PH, GA] = -v * sg * cp / r
    A[:, PH, PS] = -v * cg * sp / r
    A[:, V, R] = -ft.drag_r + 2.0 * sg / r**3 + w2 * cf * wv
    A[:, V, PH] = w2 * r * (-sf * wv + cf * (-sg * sf - cg * cf * cp))
    A[:, V, V] = -ft.drag_v
    A[:, V, GA] = -cg / r**2 + w2 * r * cf * (cg * cf + sg * sf * cp)
    A[:, V, PS] = w2 * r * cf * cg * sf * sp

    A[:, GA, R] = ft.lift_r * u1 / v - v * cg / r**2 + 2.0 * cg / (r**3 * v) + w2 * cf * gg / v
    A[:, GA, PH] = -2.0 * omega * sf * sp + w2 * r / v * (-sf * gg + cf * (-cg * sf + sg * cp * cf))
    A[:, GA, V] = (
        ft.lift_v * u1 / v - L * u1 / v**2 + cg / r + cg / (r**2 * v**2) - w2 * r * cf * gg / v**2
    )
    A[:, GA, GA] = -v * sg / r + sg / (r**2 * v) + w2 * r * cf * (-sg * cf + cg * cp * sf) / v
    A[:, GA, PS] = 2.0 * omega * cf * cp - w2 * r * cf * sg * sp * sf / v
    B[:, GA, 0] = L / v

    A[:, PS, R] = ft.lift_r * u2 / (v * cg) - v * cg * sp * tf / r**2 + rot2 / r
    A[:, PS, PH] = (
        v * cg * sp / (r * cf**2)
        - 2.0 * omega * (-tg * cp * sf - cf)
        + w2 * r * sp * (cf * cf - sf * sf) / (v * cg)
    )
    A[:, PS, V] = ft.lift_v * u2 / (v * cg) - L * u2 / (v**2 * cg) + cg * sp * tf / r - rot2 / v
    A[:, PS, GA] = (
        L * u2 * sg / (v * cg**2) - v * sg * sp * tf / r - 2.0 * omega * cp * cf / cg**2 + rot2 * tg
    )
    A[:, PS, PS] = (
        v * cg * cp * tf / r + 2.0 * omega * tg * sp * cf + w2 * r * cp * sf * cf / (v * cg)
    )
    B[:, PS, 1] = L / (v * cg)
    return TimeDerivatives(f=f, A=A, B=B, forces=ft)


def speed_from_energy(r: Array, e: Array) -> tuple[Array, Array]:
    """Exact V = sqrt(2 (1/r - e)) and dV/dr = -1/(r^2 V) (paper 000 eq. 8, not approximated)."""
    v = np.sqrt(2.0 * (1.0 / r - e))
    return v, -1.0 / (r * r * v)


@dataclass
class EnergyDerivatives:
    """dx/de for x = [r, theta, phi, gamma, psi], Jacobians, and de/dt with its gradient."""

    f: Array  # (N, 5)
    A: Array  # (N, 5, 5)
    B: Array  # (N, 5, 2)
    edot: Array  # (N,)  de/dt
    edot_x: Array  # (N, 5)
    speed: Array  # (N,)
    time: TimeDerivatives


def time_state_from_energy(x: Array, e: Array) -> tuple[Array, Array]:
    """Expand energy-form states (N, 5) at energies e to time-form states (N, 6); also dV/dr."""
    v, v_r = speed_from_energy(x[:, 0], e)
    y = np.empty((x.shape[0], N_TIME_STATES), dtype=np.result_type(x, v))
    y[:, list(ENERGY_STATES)] = x
    y[:, V] = v
    return y, v_r


def energy_dynamics(
    x: Array, u: Array, e: Array, forces: VehicleForces, omega: float
) -> EnergyDerivatives:
    """dx/de = f_x(y, u) / (de/dt) with exact Jacobians through V(r, e) (chain rule)."""
    y, v_r = time_state_from_energy(x, e)
    td = time_dynamics(y, u, forces, omega)
    assert td.A is not None and td.B is not None
    idx = list(ENERGY_STATES)
    # total derivative in the energy-form states: d/dr picks up d/dV * dV/dr
    A_t = td.A[:, :, idx].copy()
    A_t[:, :, 0] += td.A[:, :, V] * v_r[:, None]
    r = x[:, 0]
    v = y[:, V]
    # de/dt = -r'/r^2 - V V'
    edot = -td.f[:, R] / r**2 - v * td.f[:, V]
    edot_x = -A_t[:, R, :] / r[:, None] ** 2 - v[:, None] * A_t[:, V, :]
    edot_x[:, 0] += 2.0 * td.f[:, R] / r**3 - v_r * td.f[:, V]
    fx = td.f[:, idx]
    inv = 1.0 / edot
    f = fx * inv[:, None]
    A = (
        A_t[:, idx, :] * inv[:, None, None]
        - fx[:, :, None] * (edot_x * inv[:, None] ** 2)[:, None, :]
    )
    B = td.B[:, idx, :] * inv[:, None, None]
    return EnergyDerivatives(f=f, A=A, B=B, edot=edot, edot_x=edot_x, speed=v, time=td)
