"""Compiled (numba) bank-state dynamics and their RK4 propagation, for analytic force models.

The same equations as ``dynamics.time_dynamics`` wrapped by ``dynamics_bank_state`` (paper 000
eq. 1 over a rotating planet, bank angle as a state, paper 002 eq. 10 and 14), written point by
point so that a whole sweep of RK4 steps over every interval runs as one compiled loop: the numpy
form spends most of its time in per-call overhead on arrays of a few dozen rows. Only models with
closed forms are compiled (``ExponentialAtmosphere``, ``PolynomialAero``, a constant or
velocity-scheduled angle of attack); ``compiled_parameters`` returns None for any other, and the
callers keep the numpy form. ``tests/unit/test_dynamics_compiled.py`` holds both forms equal.
"""

from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from worker.solver.aerodynamics import ConstantAlpha, PolynomialAero, VelocityScheduleAlpha
from worker.solver.atmosphere import ExponentialAtmosphere
from worker.solver.forces import VehicleForces

Array = np.ndarray

NZ = 7  # r, theta, phi, V, gamma, psi, sigma (dynamics_bank_state.NZ)
NAUG = NZ + 4  # [x | Phi (7) | B- | B+ | S] columns of the augmented FOH system (foh_exact)
_LONGITUDE = 1  # index of theta in the state: absent from every rate (paper 000 eq. 1)

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
def _horner(p: Array, first: int, count: int, x: float) -> tuple[float, float]:
    """Polynomial p[first:first+count] (lowest order first) and its slope at x (aerodynamics)."""
    value = 0.0
    slope = 0.0
    for i in range(first + count - 1, first - 1, -1):
        slope = slope * x + value
        value = value * x + p[i]
    return value, slope


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
    cl, dcl = _horner(p, _COEFFS, ncl, alpha)
    if p[_CD_OF_CL] == 1.0:
        cd, dcd_dcl = _horner(p, _COEFFS + ncl, int(p[_NCD]), cl)
        dcd = dcd_dcl * dcl
    else:
        cd, dcd = _horner(p, _COEFFS + ncl, int(p[_NCD]), alpha)
    return rho, rho_r, alpha, alpha_v, cl, dcl, cd, dcd


@njit(cache=True, nogil=True, error_model="numpy")
def _rates(x: Array, w: float, s: float, p: Array, f: Array, a: Array, jac: bool) -> None:
    """dz/dt into ``f`` (7,) and, with ``jac``, s df/dz into ``a`` (7, 7) at one point.

    Only the entries that can be nonzero are written: ``a`` must come zero-filled (once).

    Forces as ``forces.VehicleForces.terms`` (exponential density, polynomial CL/CD, alpha on its
    schedule); rates and partials as ``dynamics._time_dynamics`` with u = (cos, sin) of the bank.
    """
    r, ph, v, ga, ps, sig = x[0], x[2], x[3], x[4], x[5], x[6]
    rho, rho_r, _alpha, alpha_v, cl, dcl, cd, dcd = aero_terms(r, v, p)
    kb = p[_KB]
    qk = kb * rho * v * v
    lift = qk * cl
    drag = qk * cd
    u1, u2 = math.cos(sig), math.sin(sig)
    sg, cg, sp, cp = math.sin(ga), math.cos(ga), math.sin(ps), math.cos(ps)
    sf, cf = math.sin(ph), math.cos(ph)
    # reciprocals once: a division costs several multiplications
    ir, iv, icg, icf = 1.0 / r, 1.0 / v, 1.0 / cg, 1.0 / cf
    ir2 = ir * ir
    ivcg = iv * icg
    irc = ir * icf
    tf = sf * icf
    tg = sg * icg
    om = p[_OMEGA]
    w2 = om * om
    vcg = v * cg
    vsg = v * sg
    vcg_sp = vcg * sp
    lu1 = lift * u1
    lu2 = lift * u2
    f_th = vcg_sp * irc
    f_ph = vcg * cp * ir
    f_v = -drag - sg * ir2
    f_ga = lu1 * iv + (v - ir * iv) * cg * ir
    f_ps = lu2 * ivcg + vcg_sp * tf * ir
    wv = sg * cf - cg * sf * cp
    gg = cg * cf + sg * cp * sf
    rot2 = w2 * r * sp * sf * cf * ivcg
    if om != 0.0:
        f_v += w2 * r * cf * wv
        f_ga += 2.0 * om * cf * sp + w2 * r * cf * gg * iv
        f_ps += -2.0 * om * (tg * cp * cf - sf) + rot2
    f[0] = vsg
    f[1] = f_th
    f[2] = f_ph
    f[3] = f_v
    f[4] = f_ga
    f[5] = f_ps
    f[6] = w
    if not jac:
        return
    qk_r = kb * rho_r * v * v
    qk_v = 2.0 * kb * rho * v
    lift_r = qk_r * cl
    lift_v = qk_v * cl + qk * (dcl * alpha_v)
    drag_r = qk_r * cd
    drag_v = qk_v * cd + qk * (dcd * alpha_v)
    ir3 = ir2 * ir
    iv2 = iv * iv
    a[0, 3] = s * sg
    a[0, 4] = s * vcg
    a[1, 0] = s * (-f_th * ir)
    a[1, 2] = s * (f_th * tf)
    a[1, 3] = s * (cg * sp * irc)
    a[1, 4] = s * (-vsg * sp * irc)
    a[1, 5] = s * (vcg * cp * irc)
    a[2, 0] = s * (-f_ph * ir)
    a[2, 3] = s * (cg * cp * ir)
    a[2, 4] = s * (-vsg * cp * ir)
    a[2, 5] = s * (-vcg_sp * ir)
    a_vr = -drag_r + 2.0 * sg * ir3
    a[3, 3] = s * (-drag_v)
    a_vga = -cg * ir2
    a_gar = lift_r * u1 * iv - vcg * ir2 + 2.0 * cg * ir3 * iv
    a_gav = lift_v * u1 * iv - lu1 * iv2 + cg * ir + cg * ir2 * iv2
    a_gaga = -vsg * ir + sg * ir2 * iv
    a_psr = lift_r * u2 * ivcg - vcg_sp * tf * ir2
    a_psph = vcg_sp * irc * icf
    a_psv = lift_v * u2 * ivcg - lu2 * iv2 * icg + cg * sp * tf * ir
    a_psga = lu2 * sg * ivcg * icg - vsg * sp * tf * ir
    a_psps = vcg * cp * tf * ir
    if om != 0.0:
        a_vr += w2 * cf * wv
        a[3, 2] = s * (w2 * r * (-sf * wv + cf * (-sg * sf - cg * cf * cp)))
        a_vga += w2 * r * cf * (cg * cf + sg * sf * cp)
        a[3, 5] = s * (w2 * r * cf * cg * sf * sp)
        a_gar += w2 * cf * gg * iv
        a_gaph = -2.0 * om * sf * sp + w2 * r * iv * (-sf * gg + cf * (-cg * sf + sg * cp * cf))
        a[4, 2] = s * a_gaph
        a_gav -= w2 * r * cf * gg * iv2
        a_gaga += w2 * r * cf * (-sg * cf + cg * cp * sf) * iv
        a[4, 5] = s * (2.0 * om * cf * cp - w2 * r * cf * sg * sp * sf * iv)
        a_psr += rot2 * ir
        a_psph += -2.0 * om * (-tg * cp * sf - cf) + w2 * r * sp * (cf * cf - sf * sf) * ivcg
        a_psv -= rot2 * iv
        a_psga += -2.0 * om * cp * cf * icg * icg + rot2 * tg
        a_psps += 2.0 * om * tg * sp * cf + w2 * r * cp * sf * cf * ivcg
    else:  # no rotation: these partials vanish
        a[3, 2] = a[3, 5] = a[4, 2] = a[4, 5] = 0.0
    a[3, 0] = s * a_vr
    a[3, 4] = s * a_vga
    a[4, 0] = s * a_gar
    a[4, 3] = s * a_gav
    a[4, 4] = s * a_gaga
    a[5, 0] = s * a_psr
    a[5, 2] = s * a_psph
    a[5, 3] = s * a_psv
    a[5, 4] = s * a_psga
    a[5, 5] = s * a_psps
    a[4, 6] = s * ((lift * iv) * -u2)  # d f / d sigma = B_u d u / d sigma (dynamics_bank_state)
    a[5, 6] = s * ((lift * ivcg) * u1)


@njit(cache=True, nogil=True, error_model="numpy")
def _augmented_rhs(
    tau: float,
    y: Array,
    w0: float,
    w1: float,
    s: float,
    p: Array,
    scratch: Array,
    a: Array,
    out: Array,
) -> None:
    """d/dtau of [x | Phi | B- | B+ | S] on one interval (foh_exact's module docstring);
    ``scratch`` (2, 7) holds the state and its rates."""
    x = scratch[0]
    f = scratch[1]
    for i in range(NZ):
        x[i] = y[i, 0]
    _rates(x, (1.0 - tau) * w0 + tau * w1, s, p, f, a, True)
    # A y on the structural nonzeros of A only (``_rates``): 28 of the 42 products per column
    for j in range(1, NAUG):
        y0, y2, y3, y4, y5, y6 = y[0, j], y[2, j], y[3, j], y[4, j], y[5, j], y[6, j]
        out[0, j] = a[0, 3] * y3 + a[0, 4] * y4
        out[1, j] = a[1, 0] * y0 + a[1, 2] * y2 + a[1, 3] * y3 + a[1, 4] * y4 + a[1, 5] * y5
        out[2, j] = a[2, 0] * y0 + a[2, 3] * y3 + a[2, 4] * y4 + a[2, 5] * y5
        out[3, j] = a[3, 0] * y0 + a[3, 2] * y2 + a[3, 3] * y3 + a[3, 4] * y4 + a[3, 5] * y5
        out[4, j] = (
            a[4, 0] * y0 + a[4, 2] * y2 + a[4, 3] * y3 + a[4, 4] * y4 + a[4, 5] * y5 + a[4, 6] * y6
        )
        out[5, j] = (
            a[5, 0] * y0 + a[5, 2] * y2 + a[5, 3] * y3 + a[5, 4] * y4 + a[5, 5] * y5 + a[5, 6] * y6
        )
    for i in range(NZ - 1):
        out[i, 0] = s * f[i]
        out[i, NAUG - 1] += f[i]
    # row 6 (the bank angle): A has a zero row, B = dF/dw = (0, ..., 0, s), S = f
    out[6, 0] = s * f[6]
    for j in range(1, NAUG):
        out[6, j] = 0.0
    out[6, NZ + 1] = (1.0 - tau) * s
    out[6, NZ + 2] = tau * s
    out[6, NAUG - 1] = f[6]


@njit(cache=True, nogil=True, error_model="numpy")
def interval_maps_kernel(
    x0: Array, w0: Array, w1: Array, s: Array, p: Array, substeps: int, keep: bool
) -> tuple[Array, Array]:
    """The augmented FOH system of every interval after RK4 over tau in [0, 1] (M, 7, 11) and,
    with ``keep``, at every substep, both ends included (M, substeps + 1, 7, 11); the same steps
    as ``foh_exact._rk4_unit_interval``."""
    m_count = s.size
    out = np.empty((m_count, NZ, NAUG))
    kept = np.empty((m_count, substeps + 1 if keep else 0, NZ, NAUG))
    f = np.empty((2, NZ))
    a = np.zeros((NZ, NZ))  # _rates writes only its structural nonzeros
    k1 = np.empty((NZ, NAUG))
    k2 = np.empty((NZ, NAUG))
    k3 = np.empty((NZ, NAUG))
    k4 = np.empty((NZ, NAUG))
    tmp = np.empty((NZ, NAUG))
    y = np.empty((NZ, NAUG))
    h = 1.0 / substeps
    for m in range(m_count):
        y[:, :] = 0.0
        for i in range(NZ):
            y[i, 0] = x0[m, i]
            y[i, 1 + i] = 1.0
        if keep:
            kept[m, 0] = y
        tau = 0.0
        for step in range(substeps):
            _augmented_rhs(tau, y, w0[m], w1[m], s[m], p, f, a, k1)
            _axpy(y, 0.5 * h, k1, tmp)
            _augmented_rhs(tau + 0.5 * h, tmp, w0[m], w1[m], s[m], p, f, a, k2)
            _axpy(y, 0.5 * h, k2, tmp)
            _augmented_rhs(tau + 0.5 * h, tmp, w0[m], w1[m], s[m], p, f, a, k3)
            _axpy(y, h, k3, tmp)
            _augmented_rhs(tau + h, tmp, w0[m], w1[m], s[m], p, f, a, k4)
            c = h / 6.0
            for i in range(NZ):
                for j in range(NAUG):
                    y[i, j] = y[i, j] + c * (k1[i, j] + 2.0 * k2[i, j] + 2.0 * k3[i, j] + k4[i, j])
            tau += h
            if keep:
                kept[m, step + 1] = y
        out[m] = y
    return out, kept


@njit(cache=True, nogil=True, error_model="numpy")
def _axpy(y: Array, c: float, k: Array, out: Array) -> None:
    """out = y + c k, elementwise, without a temporary."""
    for i in range(y.shape[0]):
        for j in range(y.shape[1]):
            out[i, j] = y[i, j] + c * k[i, j]


@njit(cache=True, nogil=True, error_model="numpy")
def propagate_kernel(
    x0: Array, w0: Array, w1: Array, s: Array, p: Array, substeps: int, ground_stop: bool
) -> Array:
    """End states (M, 7) of RK4 over tau in [0, 1] from each x0 under the FOH bank rate; with
    ``ground_stop``, a state below the surface after a substep becomes NaN (the guess sweep)."""
    m_count = s.size
    out = np.empty((m_count, NZ))
    f = np.empty(NZ)
    a = np.zeros((NZ, NZ))  # _rates writes only its structural nonzeros
    x = np.empty(NZ)
    xt = np.empty(NZ)
    k1 = np.empty(NZ)
    k2 = np.empty(NZ)
    k3 = np.empty(NZ)
    k4 = np.empty(NZ)
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
            _rates(x, wa, sm, p, f, a, False)
            k1[:] = sm * f
            xt[:] = x + (0.5 * h) * k1
            _rates(xt, wm, sm, p, f, a, False)
            k2[:] = sm * f
            xt[:] = x + (0.5 * h) * k2
            _rates(xt, wm, sm, p, f, a, False)
            k3[:] = sm * f
            xt[:] = x + h * k3
            _rates(xt, we, sm, p, f, a, False)
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
    out = np.empty((c, s.size + 1, NZ))
    zero = np.zeros(c)
    x = x0.copy()
    out[:, 0] = x
    for k in range(s.size):
        x = propagate_kernel(x, zero, zero, np.full(c, s[k]), p, substeps, True)
        out[:, k + 1] = x
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _end_gradient(
    x0: Array,
    w0: float,
    w1: float,
    s: float,
    lam0: Array,
    p: Array,
    substeps: int,
    a_st: Array,
    f_st: Array,
    work: Array,
    out: Array,
) -> None:
    """The gradient of lam0 . x(1) in (x0, w0, w1, s) on one interval, into ``out`` (10,).

    x(1) is the RK4 end state of ``propagate_kernel``; the gradient is the discrete adjoint of
    those steps (reverse mode through each stage), so it equals lam0' [Phi | B- | B+ | S] of
    ``interval_maps_kernel`` to rounding at a fraction of the cost: a 7-vector is carried back
    instead of a 7 x 10 sensitivity forward. ``a_st`` (4 substeps, 7, 7) and ``f_st``
    (4 substeps, 7) hold each stage's s df/dz and f; ``work`` (13, 7) is scratch.
    """
    h = 1.0 / substeps
    x, xt, f, lam, yb = work[0], work[1], work[2], work[3], work[4]
    k = work[5:9]
    kb = work[9:13]
    x[:] = x0
    offsets = (0.0, 0.5, 0.5, 1.0)
    tau = 0.0
    for step in range(substeps):
        for q in range(4):
            if q == 0:
                xt[:] = x
            else:
                c = h if q == 3 else 0.5 * h
                for i in range(NZ):
                    xt[i] = x[i] + c * k[q - 1, i]
            tq = tau + offsets[q] * h
            st = 4 * step + q
            _rates(xt, (1.0 - tq) * w0 + tq * w1, s, p, f, a_st[st], True)
            f_st[st] = f
            for i in range(NZ):
                k[q, i] = s * f[i]
        for i in range(NZ):
            x[i] = x[i] + (h / 6.0) * (k[0, i] + 2.0 * k[1, i] + 2.0 * k[2, i] + k[3, i])
        tau += h
    lam[:] = lam0
    g_w0 = 0.0
    g_w1 = 0.0
    g_s = 0.0
    weights = (h / 6.0, h / 3.0, h / 3.0, h / 6.0)
    back = (0.0, 0.5 * h, 0.5 * h, h)  # how stage q's input depends on stage q-1's slope
    for step in range(substeps - 1, -1, -1):
        tau -= h
        for q in range(4):
            for i in range(NZ):
                kb[q, i] = weights[q] * lam[i]
        for q in range(3, -1, -1):
            st = 4 * step + q
            tq = tau + offsets[q] * h
            # k_q = s f(x_q, w(tau_q)): back through A (= s df/dz), B = s e_sigma, S = f
            # yb = A' kb on the structural nonzeros of A (``_rates``; row 6 and column 1 zero)
            a = a_st[st]
            k0, k1, k2, k3, k4, k5 = kb[q, 0], kb[q, 1], kb[q, 2], kb[q, 3], kb[q, 4], kb[q, 5]
            yb[0] = a[1, 0] * k1 + a[2, 0] * k2 + a[3, 0] * k3 + a[4, 0] * k4 + a[5, 0] * k5
            yb[1] = 0.0
            yb[2] = a[1, 2] * k1 + a[3, 2] * k3 + a[4, 2] * k4 + a[5, 2] * k5
            yb[3] = (a[0, 3] * k0 + a[1, 3] * k1 + a[2, 3] * k2 + a[3, 3] * k3 + a[4, 3] * k4) + a[
                5, 3
            ] * k5
            yb[4] = (a[0, 4] * k0 + a[1, 4] * k1 + a[2, 4] * k2 + a[3, 4] * k3 + a[4, 4] * k4) + a[
                5, 4
            ] * k5
            yb[5] = a[1, 5] * k1 + a[2, 5] * k2 + a[3, 5] * k3 + a[4, 5] * k4 + a[5, 5] * k5
            yb[6] = a[4, 6] * k4 + a[5, 6] * k5
            g_w0 += (1.0 - tq) * s * kb[q, 6]
            g_w1 += tq * s * kb[q, 6]
            for i in range(NZ):
                g_s += f_st[st, i] * kb[q, i]
                lam[i] += yb[i]
            if q > 0:
                for i in range(NZ):
                    kb[q - 1, i] += back[q] * yb[i]
    out[:NZ] = lam
    out[NZ] = g_w0
    out[NZ + 1] = g_w1
    out[NZ + 2] = g_s


@njit(cache=True, nogil=True, error_model="numpy")
def lagrangian_hessian_kernel(
    x0: Array,
    w0: Array,
    w1: Array,
    s: Array,
    weights: Array,
    steps: Array,
    nb: int,
    p: Array,
    substeps: int,
) -> Array:
    """Blocks (N, nb, nb) of the Hessian of weights_k . x_k(1) in (x0, w0, w1[, s]) of every
    interval: forward differences of ``_end_gradient`` along each variable, symmetrized (the
    compiled form of ``foh_hessian.lagrangian_hessian``)."""
    n_int = s.size
    hess = np.empty((n_int, nb, nb))
    base = np.empty(NZ + 3)
    pert = np.empty(NZ + 3)
    a_st = np.zeros((4 * substeps, NZ, NZ))  # _rates writes only its structural nonzeros
    f_st = np.empty((4 * substeps, NZ))
    work = np.empty((13, NZ))
    xp = np.empty(NZ)
    for n in range(n_int):
        _end_gradient(x0[n], w0[n], w1[n], s[n], weights[n], p, substeps, a_st, f_st, work, base)
        for j in range(nb):
            if j == _LONGITUDE:  # no rate depends on the longitude: its row and column are zero
                for i in range(nb):
                    hess[n, i, j] = 0.0
                continue
            xp[:] = x0[n]
            wa, wb, sn = w0[n], w1[n], s[n]
            if j < NZ:
                xp[j] += steps[j]
            elif j == NZ:
                wa += steps[j]
            elif j == NZ + 1:
                wb += steps[j]
            else:
                sn += steps[j]
            _end_gradient(xp, wa, wb, sn, weights[n], p, substeps, a_st, f_st, work, pert)
            for i in range(nb):
                hess[n, i, j] = (pert[i] - base[i]) / steps[j]
        for i in range(nb):
            for j in range(i + 1, nb):
                mean = 0.5 * (hess[n, i, j] + hess[n, j, i])
                hess[n, i, j] = mean
                hess[n, j, i] = mean
    return hess


_warmed = False


def is_warm() -> bool:
    """Whether this process has loaded (or compiled) the kernels already."""
    return _warmed


def warm_up() -> float:
    """Compile every kernel (or load it from numba's on-disk cache) on a tiny case; seconds taken.

    The first compilation on a machine takes about 20 s; afterwards loading takes well under one.
    Worker processes call this before taking jobs, so a job's time limit never pays for it; once
    the kernels are loaded in this process it returns at once.
    """
    global _warmed
    if _warmed:
        return 0.0
    start = time.perf_counter()
    head = [6.378e6, 7.9e3, 1.2e4, 1.225, 7.2e3, 0.06, 1.0, 40.0, 4.57e3, 1.8e-6, 1.0, 2.0, 2.0]
    params = np.array([*head, 0.0, 0.02, 0.08, 0.9])  # CL and CD(CL), two coefficients each
    x0 = np.array([[1.015, 0.0, 0.0, 0.9, 0.0, 0.0, 0.3]])
    w = np.zeros(1)
    s = np.full(1, 0.01)
    interval_maps_kernel(x0, w, w, s, params, 2, True)
    propagate_kernel(x0, w, w, s, params, 2, True)
    chain_kernel(x0, s, params, 2)
    # the kernels built on these dynamics, each warmed by its own module (lazy imports: they
    # import this one)
    from worker.solver.constraints import path_compiled
    from worker.solver.transcription import foh_hessian

    foh_hessian.warm_up(params)
    path_compiled.warm_up(params)
    _warmed = True
    return time.perf_counter() - start


if __name__ == "__main__":
    print(f"compiled dynamics ready in {warm_up():.1f} s")
