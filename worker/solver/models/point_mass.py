"""3-DoF point-mass entry dynamics over a spherical, optionally rotating planet.

Time form: state y = [r, theta, phi, V, gamma, psi] (radius, longitude, latitude, planet-relative
speed, flight-path angle, heading clockwise from north), control u = [cos(sigma), sin(sigma)]
scaling the lift (so a convex relaxation of u can be used, paper 000 eq. 20-22). The equations
and their analytic partials are ``models.eom`` (paper 000 eq. 1, all nondimensional), laid out
here as arrays over nodes; complex-safe for complex-step tests.

Energy form: independent variable e = 1/r - V^2/2 (paper 000 eq. 7) and state
x = [r, theta, phi, gamma, psi], with the exact V = sqrt(2 (1/r - e)) (not the approximation of
eq. 8) and the exact de/dt = -r'/r^2 - V V' (equal to D V without rotation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worker.solver.forces import ForceTerms, VehicleForces
from worker.solver.models import eom

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
    """``time_dynamics`` and r^3 (None without Jacobians), which the energy form needs again.

    Rates and partials are ``models.eom`` in the numpy form (divisions, rotation terms added one
    by one); this function lays them out as f (N, 6), A (N, 6, 6) and B (N, 6, 2).
    """
    r, v, ga, ps, ph = y[:, R], y[:, V], y[:, GA], y[:, PS], y[:, PH]
    u1, u2 = u[:, 0], u[:, 1]
    ft = forces.terms(r, v, alpha_deg)
    k = eom.kinematics(r, ph, v, ga, ps, False)
    rt = eom.rates(k, r, v, ft.lift, ft.drag, u1, u2, omega, False, False)
    n = y.shape[0]
    f = np.empty((n, 6), dtype=np.result_type(y, u, ft.lift))
    for i, rate in enumerate(rt):
        f[:, i] = rate
    if not jacobians:
        return TimeDerivatives(f=f, A=None, B=None, forces=ft), None
    p = eom.partials(
        k, rt, r, v, ft.lift, ft.lift_r, ft.lift_v, ft.drag_r, ft.drag_v, u1, u2, omega,
        False, False,
    )  # fmt: skip
    A = np.zeros((n, 6, 6), dtype=f.dtype)
    B = np.zeros((n, 6, 2), dtype=f.dtype)
    for (i, j), name in STATE_PARTIALS.items():
        A[:, i, j] = getattr(p, name)
    B[:, GA, 0] = p.gamma_u1
    B[:, PS, 1] = p.psi_u2
    return TimeDerivatives(f=f, A=A, B=B, forces=ft), k.d.r3


STATE_PARTIALS = {
    (R, V): "r_v",
    (R, GA): "r_gamma",
    (TH, R): "theta_r",
    (TH, PH): "theta_phi",
    (TH, V): "theta_v",
    (TH, GA): "theta_gamma",
    (TH, PS): "theta_psi",
    (PH, R): "phi_r",
    (PH, V): "phi_v",
    (PH, GA): "phi_gamma",
    (PH, PS): "phi_psi",
    (V, R): "v_r",
    (V, PH): "v_phi",
    (V, V): "v_v",
    (V, GA): "v_gamma",
    (V, PS): "v_psi",
    (GA, R): "gamma_r",
    (GA, PH): "gamma_phi",
    (GA, V): "gamma_v",
    (GA, GA): "gamma_gamma",
    (GA, PS): "gamma_psi",
    (PS, R): "psi_r",
    (PS, PH): "psi_phi",
    (PS, V): "psi_v",
    (PS, GA): "psi_gamma",
    (PS, PS): "psi_psi",
}
"""(row, column) of A = df/dy holding each field of ``models.eom.Partials``."""


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
