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
    return _time_dynamics(y, u, forces, omega, alpha_deg, jacobians=jacobians)[0]


def _time_dynamics(
    y: Array,
    u: Array,
    forces: VehicleForces,
    omega: float,
    alpha_deg: Array | None = None,
    *,
    jacobians: bool = True,
) -> tuple[TimeDerivatives, Array | None]:
    """``time_dynamics`` and r^3 (None without Jacobians), which the energy form needs again."""
    r, v, ga, ps, ph = y[:, R], y[:, V], y[:, GA], y[:, PS], y[:, PH]
    u1, u2 = u[:, 0], u[:, 1]
    ft = forces.terms(r, v, alpha_deg)
    L, D = ft.lift, ft.drag
    sg, cg, sp, cp, sf, cf = np.sin(ga), np.cos(ga), np.sin(ps), np.cos(ps), np.sin(ph), np.cos(ph)
    tf = sf / cf
    tg = sg / cg
    rotating = omega != 0.0
    w2 = omega * omega
    n = y.shape[0]
    f = np.empty((n, 6), dtype=np.result_type(y, u, L))
    # shared subexpressions (each evaluated exactly as it appears in the formulas below)
    r2 = r**2
    vcg = v * cg
    vsg = v * sg
    rcf = r * cf
    vcg_sp = vcg * sp
    lu1 = L * u1
    lu2 = L * u2
    f_th = vcg_sp / rcf
    f_ph = vcg * cp / r
    f[:, R] = vsg  # r' = V sin(gamma)
    f[:, TH] = f_th  # theta' = V cos(gamma) sin(psi) / (r cos(phi))
    f[:, PH] = f_ph  # phi' = V cos(gamma) cos(psi) / r
    # The rotation terms (omega != 0) are added last, so a non-rotating planet skips them.
    # V' = -D - sin(gamma)/r^2 + W^2 r cos(phi) (sin(gamma) cos(phi) - cos(gamma) sin(phi) cos(psi))
    f_v = -D - sg / r2
    # gamma' = L u1 / V + (V - 1/(r V)) cos(gamma)/r + 2 W cos(phi) sin(psi)
    #          + W^2 r cos(phi) (cos(gamma) cos(phi) + sin(gamma) cos(psi) sin(phi)) / V
    f_ga = lu1 / v + (v - 1.0 / (r * v)) * cg / r
    # psi' = L u2 / (V cos(gamma)) + V cos(gamma) sin(psi) tan(phi) / r
    #        - 2 W (tan(gamma) cos(psi) cos(phi) - sin(phi))
    #        + W^2 r sin(psi) sin(phi) cos(phi) / (V cos(gamma))
    f_ps = lu2 / vcg + vcg_sp * tf / r
    if rotating:
        wv = sg * cf - cg * sf * cp
        gg = cg * cf + sg * cp * sf
        rot2 = w2 * r * sp * sf * cf / vcg
        f_v = f_v + w2 * r * cf * wv
        f_ga = f_ga + 2.0 * omega * cf * sp + w2 * r * cf * gg / v
        f_ps = f_ps - 2.0 * omega * (tg * cp * cf - sf) + rot2
    f[:, V] = f_v
    f[:, GA] = f_ga
    f[:, PS] = f_ps
    if not jacobians:
        return TimeDerivatives(f=f, A=None, B=None, forces=ft), None
    r3 = r**3
    A = np.zeros((n, 6, 6), dtype=f.dtype)
    B = np.zeros((n, 6, 2), dtype=f.dtype)
    A[:, R, V] = sg
    A[:, R, GA] = vcg
    A[:, TH, R] = -f_th / r
    A[:, TH, PH] = f_th * tf
    A[:, TH, V] = cg * sp / rcf
    A[:, TH, GA] = -vsg * sp / rcf
    A[:, TH, PS] = vcg * cp / rcf
    A[:, PH, R] = -f_ph / r
    A[:, PH, V] = cg * cp / r
    A[:, PH, GA] = -vsg * cp / r
    A[:, PH, PS] = -vcg_sp / r
    a_vr = -ft.drag_r + 2.0 * sg / r3
    A[:, V, V] = -ft.drag_v
    a_vga = -cg / r2

    a_gar = ft.lift_r * u1 / v - vcg / r2 + 2.0 * cg / (r3 * v)
    a_gav = ft.lift_v * u1 / v - lu1 / v**2 + cg / r + cg / (r2 * v**2)
    a_gaga = -vsg / r + sg / (r2 * v)
    B[:, GA, 0] = L / v

    a_psr = ft.lift_r * u2 / vcg - vcg_sp * tf / r2
    a_psph = vcg_sp / (r * cf**2)
    a_psv = ft.lift_v * u2 / vcg - lu2 / (v**2 * cg) + cg * sp * tf / r
    a_psga = lu2 * sg / (v * cg**2) - vsg * sp * tf / r
    a_psps = vcg * cp * tf / r
    if rotating:
        a_vr = a_vr + w2 * cf * wv
        A[:, V, PH] = w2 * r * (-sf * wv + cf * (-sg * sf - cg * cf * cp))
        a_vga = a_vga + w2 * r * cf * (cg * cf + sg * sf * cp)
        A[:, V, PS] = w2 * r * cf * cg * sf * sp
        a_gar = a_gar + w2 * cf * gg / v
        A[:, GA, PH] = -2.0 * omega * sf * sp + w2 * r / v * (
            -sf * gg + cf * (-cg * sf + sg * cp * cf)
        )
        a_gav = a_gav - w2 * r * cf * gg / v**2
        a_gaga = a_gaga + w2 * r * cf * (-sg * cf + cg * cp * sf) / v
        A[:, GA, PS] = 2.0 * omega * cf * cp - w2 * r * cf * sg * sp * sf / v
        a_psr = a_psr + rot2 / r
        a_psph = (
            a_psph - 2.0 * omega * (-tg * cp * sf - cf) + w2 * r * sp * (cf * cf - sf * sf) / vcg
        )
        a_psv = a_psv - rot2 / v
        a_psga = a_psga - 2.0 * omega * cp * cf / cg**2 + rot2 * tg
        a_psps = a_psps + 2.0 * omega * tg * sp * cf + w2 * r * cp * sf * cf / vcg
    A[:, V, R] = a_vr
    A[:, V, GA] = a_vga
    A[:, GA, R] = a_gar
    A[:, GA, V] = a_gav
    A[:, GA, GA] = a_gaga
    A[:, PS, R] = a_psr
    A[:, PS, PH] = a_psph
    A[:, PS, V] = a_psv
    A[:, PS, GA] = a_psga
    A[:, PS, PS] = a_psps
    B[:, PS, 1] = L / vcg
    return TimeDerivatives(f=f, A=A, B=B, forces=ft), r3


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
    y[:, R : PH + 1] = x[:, :3]  # ENERGY_STATES: r, theta, phi, then gamma, psi after V
    y[:, V] = v
    y[:, GA:] = x[:, 3:]
    return y, v_r


@dataclass
class EnergyRates:
    """dx/de and de/dt without Jacobians (enough to judge a step), and the forces used."""

    f: Array  # (N, 5)
    edot: Array  # (N,)  de/dt
    speed: Array  # (N,)
    time: TimeDerivatives  # values only: its A and B are None


def _edot(td: TimeDerivatives, r: Array, v: Array) -> Array:
    """de/dt = -r'/r^2 - V V' (exact, paper 000 eq. 7 differentiated in time)."""
    return -td.f[:, R] / r**2 - v * td.f[:, V]


def energy_rates(x: Array, u: Array, e: Array, forces: VehicleForces, omega: float) -> EnergyRates:
    """dx/de = f_x(y, u) / (de/dt) and de/dt only: the values of ``energy_dynamics``."""
    y, _ = time_state_from_energy(x, e)
    td = time_dynamics(y, u, forces, omega, jacobians=False)
    v = y[:, V]
    edot = _edot(td, x[:, 0], v)
    inv = 1.0 / edot
    return EnergyRates(f=td.f[:, list(ENERGY_STATES)] * inv[:, None], edot=edot, speed=v, time=td)


def energy_dynamics(
    x: Array, u: Array, e: Array, forces: VehicleForces, omega: float
) -> EnergyDerivatives:
    """dx/de = f_x(y, u) / (de/dt) with exact Jacobians through V(r, e) (chain rule)."""
    y, v_r = time_state_from_energy(x, e)
    td, r3 = _time_dynamics(y, u, forces, omega)
    assert td.A is not None and td.B is not None and r3 is not None
    idx = list(ENERGY_STATES)
    # total derivative in the energy-form states: d/dr picks up d/dV * dV/dr
    A_t = td.A[:, :, idx]  # advanced indexing: already a copy
    A_t[:, :, 0] += td.A[:, :, V] * v_r[:, None]
    r = x[:, 0]
    v = y[:, V]
    edot = _edot(td, r, v)
    edot_x = -A_t[:, R, :] / r[:, None] ** 2 - v[:, None] * A_t[:, V, :]
    edot_x[:, 0] += 2.0 * td.f[:, R] / r3 - v_r * td.f[:, V]
    fx = td.f[:, idx]
    inv = 1.0 / edot
    f = fx * inv[:, None]
    A = (
        A_t[:, idx, :] * inv[:, None, None]
        - fx[:, :, None] * (edot_x * inv[:, None] ** 2)[:, None, :]
    )
    B = td.B[:, idx, :] * inv[:, None, None]
    return EnergyDerivatives(f=f, A=A, B=B, edot=edot, edot_x=edot_x, speed=v, time=td)
