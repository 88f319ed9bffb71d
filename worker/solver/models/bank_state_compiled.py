"""The bank-state model's compiled (numba) form: force parameters, point rates, RK4 sweeps.

The equations are ``models.eom`` (paper 000 eq. 1 over a rotating planet) with the bank angle as
a state and its rate as the control (paper 002 eq. 10 and 14), evaluated point by point so a
whole sweep of RK4 steps over every interval runs as one compiled loop: the numpy form spends
most of its time in per-call overhead on arrays of a few dozen rows. Only force models with
closed forms are compiled (``ExponentialAtmosphere``, ``PolynomialAero``, a constant or
velocity-scheduled angle of attack); ``compiled_parameters`` returns None for any other, and the
callers keep the numpy form. ``tests/unit/test_dynamics_compiled.py`` holds both forms equal.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from worker.solver.aero_models import PolynomialAero
from worker.solver.alpha_schedules import ConstantAlpha, VelocityScheduleAlpha
from worker.solver.atmosphere import ExponentialAtmosphere
from worker.solver.forces import VehicleForces
from worker.solver.models import eom
from worker.solver.models.layout import BANK_STATE
from worker.solver.polynomial import horner

Array = np.ndarray

N = BANK_STATE.size  # r, theta, phi, V, gamma, psi, sigma
AUGMENTED_COLUMNS = N + 4  # [x | Phi (7) | B- | B+ | S] of the augmented FOH system (foh_exact)
LONGITUDE = BANK_STATE.index("longitude_deg")  # absent from every rate (paper 000 eq. 1)
_SIGMA = BANK_STATE.index("bank_deg")

# Layout of the parameter vector
_R0, _VS, _KB, _RHO0, _HS, _OMEGA, _ALPHA_MODE, _ALPHA0, _VBREAK, _KSLOPE, _CD_OF_CL = range(11)
_NCL, _NCD, _COEFFS = 11, 12, 13


def compiled_parameters(forces: VehicleForces, omega: float) -> Array | None:
    """The models of ``forces`` and the rotation rate packed for the kernels; None when a model
    has no compiled form (tables, splines, US76, optimized angle of attack)."""
    atm, aero, sched = forces.atmosphere, forces.aero, forces.alpha_schedule
    if not isinstance(atm, ExponentialAtmosphere) or not isinstance(aero, PolynomialAero):
        return None
    if isinstance(sched, ConstantAlpha):
        mode, alpha0, vbreak, kslope = 0.0, sched.value_deg, 0.0, 0.0
    elif isinstance(sched, VelocityScheduleAlpha):
        mode, alpha0 = 1.0, sched.alpha_max_deg
        vbreak = sched.velocity_break_m_s
        kslope = sched.slope_coefficient / sched.velocity_scale_m_s**2
    else:
        return None
    head = [
        forces.scales.radius_m,
        forces.scales.speed_m_s,
        forces.ballistic_factor,
        atm.rho0,
        atm.scale_height_m,
        float(omega),
        mode,
        alpha0,
        vbreak,
        kslope,
        1.0 if aero.cd_argument == "cl" else 0.0,
        float(len(aero.cl_coefficients)),
        float(len(aero.cd_coefficients)),
    ]
    return np.array([*head, *aero.cl_coefficients, *aero.cd_coefficients])


def float_arrays(*arrays: Array) -> list[Array]:
    """The arrays as C-contiguous float64 (the kernels' argument types: one compiled version)."""
    return [np.ascontiguousarray(a, dtype=np.float64) for a in arrays]


@njit(cache=True, nogil=True, error_model="numpy")
def aero_terms(
    r: float, v: float, p: Array
) -> tuple[float, float, float, float, float, float, float, float]:
    """Density, d rho / d r, alpha (deg), d alpha / d V and CL, CD with their slopes in alpha at
    nondimensional (r, V): ``forces.VehicleForces.terms`` for the compiled models."""
    rho = p[_RHO0] * math.exp(-((r - 1.0) * p[_R0]) / p[_HS])
    rho_r = (-rho / p[_HS]) * p[_R0]
    alpha = p[_ALPHA0]
    alpha_v = 0.0
    if p[_ALPHA_MODE] == 1.0:
        dv = v * p[_VS] - p[_VBREAK]
        if v * p[_VS] <= p[_VBREAK]:
            alpha = p[_ALPHA0] - p[_KSLOPE] * dv * dv
            alpha_v = -2.0 * p[_KSLOPE] * dv * p[_VS]
    ncl = int(p[_NCL])
    cl, dcl = horner(p, _COEFFS, ncl, alpha)
    if p[_CD_OF_CL] == 1.0:
        cd, dcd_dcl = horner(p, _COEFFS + ncl, int(p[_NCD]), cl)
        dcd = dcd_dcl * dcl
    else:
        cd, dcd = horner(p, _COEFFS + ncl, int(p[_NCD]), alpha)
    return rho, rho_r, alpha, alpha_v, cl, dcl, cd, dcd


@njit(cache=True, nogil=True, error_model="numpy")
def point_rates(x: Array, w: float, s: float, p: Array, f: Array, a: Array, jac: bool) -> None:
    """dz/dt into ``f`` (7,) and, with ``jac``, s df/dz into ``a`` (7, 7) at one point.

    Only the entries that can be nonzero are written: ``a`` must come zero-filled (once).
    Forces as ``forces.VehicleForces.terms`` (exponential density, polynomial CL/CD, alpha on
    its schedule); rates and partials ``models.eom`` in the kernels' form (reciprocals, grouped
    rotation terms), with u = (cos, sin) of the bank as ``models.bank_state``.
    """
    r, ph, v, ga, ps, sig = x[0], x[2], x[3], x[4], x[5], x[_SIGMA]
    rho, rho_r, _alpha, alpha_v, cl, dcl, cd, dcd = aero_terms(r, v, p)
    kb = p[_KB]
    qk = kb * rho * v * v
    lift = qk * cl
    drag = qk * cd
    u1, u2 = math.cos(sig), math.sin(sig)
    om = p[_OMEGA]
    k = eom.kinematics(r, ph, v, ga, ps, True)
    rt = eom.rates(k, r, v, lift, drag, u1, u2, om, True, True)
    f[0], f[1], f[2], f[3], f[4], f[5] = rt
    f[_SIGMA] = w
    if not jac:
        return
    qk_r = kb * rho_r * v * v
    qk_v = 2.0 * kb * rho * v
    lift_r = qk_r * cl
    lift_v = qk_v * cl + qk * (dcl * alpha_v)
    drag_r = qk_r * cd
    drag_v = qk_v * cd + qk * (dcd * alpha_v)
    d = eom.partials(k, rt, r, v, lift, lift_r, lift_v, drag_r, drag_v, u1, u2, om, True, True)
    a[0, 3] = s * d.r_v
    a[0, 4] = s * d.r_gamma
    a[1, 0] = s * d.theta_r
    a[1, 2] = s * d.theta_phi
    a[1, 3] = s * d.theta_v
    a[1, 4] = s * d.theta_gamma
    a[1, 5] = s * d.theta_psi
    a[2, 0] = s * d.phi_r
    a[2, 3] = s * d.phi_v
    a[2, 4] = s * d.phi_gamma
    a[2, 5] = s * d.phi_psi
    a[3, 0] = s * d.v_r
    a[3, 3] = s * d.v_v
    a[3, 4] = s * d.v_gamma
    a[4, 0] = s * d.gamma_r
    a[4, 3] = s * d.gamma_v
    a[4, 4] = s * d.gamma_gamma
    a[5, 0] = s * d.psi_r
    a[5, 2] = s * d.psi_phi
    a[5, 3] = s * d.psi_v
    a[5, 4] = s * d.psi_gamma
    a[5, 5] = s * d.psi_psi
    if om != 0.0:
        a[3, 2] = s * d.v_phi
        a[3, 5] = s * d.v_psi
        a[4, 2] = s * d.gamma_phi
        a[4, 5] = s * d.gamma_psi
    else:  # no rotation: these partials vanish
        a[3, 2] = a[3, 5] = a[4, 2] = a[4, 5] = 0.0
    # d f / d sigma = B_u d u / d sigma with d u / d sigma = (-sin sigma, cos sigma)
    a[4, _SIGMA] = s * (d.gamma_u1 * -u2)
    a[5, _SIGMA] = s * (d.psi_u2 * u1)


@njit(cache=True, nogil=True, error_model="numpy")
def propagate_kernel(
    x0: Array, w0: Array, w1: Array, s: Array, p: Array, substeps: int, ground_stop: bool
) -> Array:
    """End states (M, 7) of RK4 over tau in [0, 1] from each x0 under the FOH bank rate; with
    ``ground_stop``, a state below the surface after a substep becomes NaN (the guess sweep)."""
    m_count = s.size
    out = np.empty((m_count, N))
    f = np.empty(N)
    a = np.zeros((N, N))  # point_rates writes only its structural nonzeros
    x = np.empty(N)
    xt = np.empty(N)
    k1 = np.empty(N)
    k2 = np.empty(N)
    k3 = np.empty(N)
    k4 = np.empty(N)
    h = 1.0 / substeps
    for m in range(m_count):
        x[:] = x0[m]
        sm = s[m]
        tau = 0.0
        for _ in range(substeps):
            wa = (1.0 - tau) * w0[m] + tau * w1[m]
            tm = tau + 0.5 * h
            wm = (1.0 - tm) * w0[m] + tm * w1[m]
            te = tau + h
            we = (1.0 - te) * w0[m] + te * w1[m]
            point_rates(x, wa, sm, p, f, a, False)
            k1[:] = sm * f
            xt[:] = x + (0.5 * h) * k1
            point_rates(xt, wm, sm, p, f, a, False)
            k2[:] = sm * f
            xt[:] = x + (0.5 * h) * k2
            point_rates(xt, wm, sm, p, f, a, False)
            k3[:] = sm * f
            xt[:] = x + h * k3
            point_rates(xt, we, sm, p, f, a, False)
            k4[:] = sm * f
            x[:] = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            tau += h
            if ground_stop and x[0] < 1.0:
                x[:] = np.nan
        out[m] = x
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def chain_kernel(x0: Array, s: Array, p: Array, substeps: int) -> Array:
    """Nodes (C, N + 1, 7) of one propagation from each start state x0 (C, 7) over the
    intervals ``s`` at zero bank rate (constant bank), interval after interval, a state below
    the surface turning NaN (``propagate_kernel``'s ground stop): the guess sweep in one call."""
    c = x0.shape[0]
    out = np.empty((c, s.size + 1, N))
    zero = np.zeros(c)
    x = x0.copy()
    out[:, 0] = x
    for k in range(s.size):
        x = propagate_kernel(x, zero, zero, np.full(c, s[k]), p, substeps, True)
        out[:, k + 1] = x
    return out
