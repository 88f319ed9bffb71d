"""The point-mass equations of motion and their partials: the one source of every form.

Paper 000 eq. 1 (Lu 2014, time form) over a spherical planet rotating at ``omega``, state
[r, theta, phi, V, gamma, psi] nondimensional (units.Scales), lift scaled by u = (u1, u2)
(cos and sin of the bank, or a relaxation of them, paper 000 eq. 20-22). The functions are
written with numpy ufuncs on scalars or arrays: the numpy path calls them on arrays of nodes
(complex-safe, for complex-step tests), the compiled kernels and the scalar integrator call
them compiled by ``numba`` on floats (``register_jitable``).

Three forms run them and each keeps the arithmetic it was recorded with (bitwise): the numpy
path divides (``recip=False``) and adds the rotation terms one by one (``grouped=False``); the
scalar integrator divides and adds each rate's rotation terms as one sum (``grouped=True``);
the kernels hold reciprocals of the denominators and multiply (``recip=True``, a division costs
several multiplications) with grouped rotation terms. ``Denominators`` holds what each quotient
is divided by (or multiplied with): ``_over(x, d)`` is x / d or x * d, ``_over2(x, d1, d2)`` is
x / (d1 d2) or (x d1) d2.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba.extending import register_jitable

Value = Any  # a float, or an array of nodes (real or complex)


class Denominators(NamedTuple):
    """What each quotient of the equations divides by: the quantity itself, or its reciprocal.

    ``rcf2`` and ``vcg2`` split r cos(phi)^2 and V cos(gamma)^2 as the two forms do: numpy
    divides by r (cos phi)^2, the kernels multiply by 1/(r cos phi) and then by 1/cos(phi).
    """

    r: Value
    v: Value
    cg: Value
    cf: Value
    rcf: Value  # r cos(phi)
    rv: Value  # r V
    r2: Value
    r3: Value
    v2: Value
    vcg: Value  # V cos(gamma)
    rcf2_a: Value
    rcf2_b: Value
    vcg2_a: Value
    vcg2_b: Value


class Kinematics(NamedTuple):
    """The trigonometric and kinematic subexpressions shared by the rates and their partials."""

    sg: Value
    cg: Value
    sp: Value
    cp: Value
    sf: Value
    cf: Value
    tf: Value  # tan(phi)
    tg: Value  # tan(gamma)
    vcg: Value
    vsg: Value
    vcg_sp: Value
    d: Denominators


class Rates(NamedTuple):
    """d/dt of [r, theta, phi, V, gamma, psi]."""

    r: Value
    theta: Value
    phi: Value
    v: Value
    gamma: Value
    psi: Value


class Partials(NamedTuple):
    """The structurally nonzero partials of ``Rates`` in the state (``x_y`` = d x' / d y) and
    in the lift scalings (``gamma_u1`` = d gamma' / d u1, ``psi_u2`` = d psi' / d u2).

    The ``*_phi`` and ``*_psi`` partials of V' and gamma' come only from the rotation and are
    zero without it. No rate depends on the longitude theta.
    """

    r_v: Value
    r_gamma: Value
    theta_r: Value
    theta_phi: Value
    theta_v: Value
    theta_gamma: Value
    theta_psi: Value
    phi_r: Value
    phi_v: Value
    phi_gamma: Value
    phi_psi: Value
    v_r: Value
    v_phi: Value
    v_v: Value
    v_gamma: Value
    v_psi: Value
    gamma_r: Value
    gamma_phi: Value
    gamma_v: Value
    gamma_gamma: Value
    gamma_psi: Value
    psi_r: Value
    psi_phi: Value
    psi_v: Value
    psi_gamma: Value
    psi_psi: Value
    gamma_u1: Value
    psi_u2: Value


@register_jitable
def _over(x: Value, d: Value, recip: bool) -> Value:
    """x / d, or x * d when ``d`` holds the reciprocal (``recip``)."""
    if recip:
        return x * d
    return x / d


@register_jitable
def _over2(x: Value, d1: Value, d2: Value, recip: bool) -> Value:
    """x / (d1 d2), or (x d1) d2 when ``d1`` and ``d2`` hold reciprocals (``recip``)."""
    if recip:
        return x * d1 * d2
    return x / (d1 * d2)


@register_jitable
def _add2(a: Value, x: Value, y: Value, grouped: bool) -> Value:
    """a + x + y, summed as a + (x + y) when ``grouped``, else as (a + x) + y."""
    if grouped:
        return a + (x + y)
    return a + x + y


@register_jitable
def denominators(r: Value, v: Value, cg: Value, cf: Value, recip: bool) -> Denominators:
    """The ``Denominators`` of the equations at (r, V, cos gamma, cos phi)."""
    if recip:
        ir, iv, icg, icf = 1.0 / r, 1.0 / v, 1.0 / cg, 1.0 / cf
        ir2 = ir * ir
        irc = ir * icf
        ivcg = iv * icg
        return Denominators(
            ir, iv, icg, icf, irc, ir * iv, ir2, ir2 * ir, iv * iv, ivcg, irc, icf, ivcg, icg
        )
    vcg = v * cg
    return Denominators(
        r, v, cg, cf, r * cf, r * v, r * r, r**3, v * v, vcg, r, cf * cf, v, cg * cg
    )


@register_jitable
def kinematics(r: Value, ph: Value, v: Value, ga: Value, ps: Value, recip: bool) -> Kinematics:
    """The shared subexpressions at (r, phi, V, gamma, psi), each computed once."""
    sg, cg, sp, cp, sf, cf = np.sin(ga), np.cos(ga), np.sin(ps), np.cos(ps), np.sin(ph), np.cos(ph)
    d = denominators(r, v, cg, cf, recip)
    vcg = v * cg
    return Kinematics(
        sg, cg, sp, cp, sf, cf, _over(sf, d.cf, recip), _over(sg, d.cg, recip),
        vcg, v * sg, vcg * sp, d,
    )  # fmt: skip


@register_jitable
def rates(
    k: Kinematics,
    r: Value,
    v: Value,
    lift: Value,
    drag: Value,
    u1: Value,
    u2: Value,
    omega: float,
    recip: bool,
    grouped: bool,
) -> Rates:
    """d/dt of [r, theta, phi, V, gamma, psi] (paper 000 eq. 1), lift and drag in g0.

    r' = V sin(gamma); theta' = V cos(gamma) sin(psi) / (r cos(phi));
    phi' = V cos(gamma) cos(psi) / r;
    V' = -D - sin(gamma)/r^2 + W^2 r cos(phi) (sin(gamma) cos(phi) - cos(gamma) sin(phi) cos(psi));
    gamma' = L u1 / V + (V - 1/(r V)) cos(gamma)/r + 2 W cos(phi) sin(psi)
             + W^2 r cos(phi) (cos(gamma) cos(phi) + sin(gamma) cos(psi) sin(phi)) / V;
    psi' = L u2 / (V cos(gamma)) + V cos(gamma) sin(psi) tan(phi) / r
           - 2 W (tan(gamma) cos(psi) cos(phi) - sin(phi))
           + W^2 r sin(psi) sin(phi) cos(phi) / (V cos(gamma)).
    The rotation terms (W = omega != 0) are added last, so a non-rotating planet skips them.
    """
    d = k.d
    sg, cg, sp, cp, sf, cf = k.sg, k.cg, k.sp, k.cp, k.sf, k.cf
    f_v = -drag - _over(sg, d.r2, recip)
    f_ga = _over(lift * u1, d.v, recip) + _over((v - _over(1.0, d.rv, recip)) * cg, d.r, recip)
    f_ps = _over(lift * u2, d.vcg, recip) + _over(k.vcg_sp * k.tf, d.r, recip)
    if omega != 0.0:
        w2 = omega * omega
        wv = sg * cf - cg * sf * cp
        gg = cg * cf + sg * cp * sf
        rot2 = _over(w2 * r * sp * sf * cf, d.vcg, recip)
        f_v = f_v + w2 * r * cf * wv
        f_ga = _add2(f_ga, 2.0 * omega * cf * sp, _over(w2 * r * cf * gg, d.v, recip), grouped)
        f_ps = _add2(f_ps, -2.0 * omega * (k.tg * cp * cf - sf), rot2, grouped)
    return Rates(
        k.vsg, _over(k.vcg_sp, d.rcf, recip), _over(k.vcg * cp, d.r, recip), f_v, f_ga, f_ps
    )


@register_jitable
def partials(
    k: Kinematics,
    f: Rates,
    r: Value,
    v: Value,
    lift: Value,
    lift_r: Value,
    lift_v: Value,
    drag_r: Value,
    drag_v: Value,
    u1: Value,
    u2: Value,
    omega: float,
    recip: bool,
    grouped: bool,
) -> Partials:
    """The nonzero partials of ``rates`` (``Partials``); ``lift_*``, ``drag_*`` are the forces'
    total partials in r and V (including a scheduled angle of attack's dependence on V)."""
    d = k.d
    sg, cg, sp, cp, sf, cf, tf, tg = k.sg, k.cg, k.sp, k.cp, k.sf, k.cf, k.tf, k.tg
    vcg, vsg, vcg_sp = k.vcg, k.vsg, k.vcg_sp
    lu1 = lift * u1
    lu2 = lift * u2
    a_vr = -drag_r + _over(2.0 * sg, d.r3, recip)
    a_vga = _over(-cg, d.r2, recip)
    a_gar = (
        _over(lift_r * u1, d.v, recip)
        - _over(vcg, d.r2, recip)
        + _over2(2.0 * cg, d.r3, d.v, recip)
    )
    a_gav = (
        _over(lift_v * u1, d.v, recip)
        - _over(lu1, d.v2, recip)
        + _over(cg, d.r, recip)
        + _over2(cg, d.r2, d.v2, recip)
    )
    a_gaga = _over(-vsg, d.r, recip) + _over2(sg, d.r2, d.v, recip)
    a_psr = _over(lift_r * u2, d.vcg, recip) - _over(vcg_sp * tf, d.r2, recip)
    a_psph = _over2(vcg_sp, d.rcf2_a, d.rcf2_b, recip)
    a_psv = (
        _over(lift_v * u2, d.vcg, recip)
        - _over2(lu2, d.v2, d.cg, recip)
        + _over(cg * sp * tf, d.r, recip)
    )
    a_psga = _over2(lu2 * sg, d.vcg2_a, d.vcg2_b, recip) - _over(vsg * sp * tf, d.r, recip)
    a_psps = _over(vcg * cp * tf, d.r, recip)
    a_vph = a_vps = a_gaph = a_gaps = 0.0 * r
    if omega != 0.0:
        w2 = omega * omega
        wv = sg * cf - cg * sf * cp
        gg = cg * cf + sg * cp * sf
        rot2 = _over(w2 * r * sp * sf * cf, d.vcg, recip)
        a_vr = a_vr + w2 * cf * wv
        a_vph = w2 * r * (-sf * wv + cf * (-sg * sf - cg * cf * cp))
        a_vga = a_vga + w2 * r * cf * (cg * cf + sg * sf * cp)
        a_vps = w2 * r * cf * cg * sf * sp
        a_gar = a_gar + _over(w2 * cf * gg, d.v, recip)
        a_gaph = -2.0 * omega * sf * sp + _over(w2 * r, d.v, recip) * (
            -sf * gg + cf * (-cg * sf + sg * cp * cf)
        )
        a_gav = a_gav - _over(w2 * r * cf * gg, d.v2, recip)
        a_gaga = a_gaga + _over(w2 * r * cf * (-sg * cf + cg * cp * sf), d.v, recip)
        a_gaps = 2.0 * omega * cf * cp - _over(w2 * r * cf * sg * sp * sf, d.v, recip)
        a_psr = a_psr + _over(rot2, d.r, recip)
        a_psph = _add2(
            a_psph,
            -2.0 * omega * (-tg * cp * sf - cf),
            _over(w2 * r * sp * (cf * cf - sf * sf), d.vcg, recip),
            grouped,
        )
        a_psv = a_psv - _over(rot2, d.v, recip)
        a_psga = _add2(
            a_psga, _over2(-2.0 * omega * cp * cf, d.cg, d.cg, recip), rot2 * tg, grouped
        )
        a_psps = _add2(
            a_psps,
            2.0 * omega * tg * sp * cf,
            _over(w2 * r * cp * sf * cf, d.vcg, recip),
            grouped,
        )
    return Partials(
        sg, vcg,
        _over(-f.theta, d.r, recip), f.theta * tf, _over(cg * sp, d.rcf, recip),
        _over(-vsg * sp, d.rcf, recip), _over(vcg * cp, d.rcf, recip),
        _over(-f.phi, d.r, recip), _over(cg * cp, d.r, recip), _over(-vsg * cp, d.r, recip),
        _over(-vcg_sp, d.r, recip),
        a_vr, a_vph, -drag_v, a_vga, a_vps,
        a_gar, a_gaph, a_gav, a_gaga, a_gaps,
        a_psr, a_psph, a_psv, a_psga, a_psps,
        _over(lift, d.v, recip), _over(lift, d.vcg, recip),
    )  # fmt: skip
