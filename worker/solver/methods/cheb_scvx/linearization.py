"""The Chebyshev SCvx's reference and its linearization: collocation defects and Jacobians at
the control points (paper 001 eqs. 26-29), path quantities in log form with their gradients
(eq. 33), zone distances at the points and between them, waypoint misses at the joints.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from worker.solver.aero_models import LiftShareAero
from worker.solver.constraints.log_path import log_path_rows
from worker.solver.constraints.no_fly import zone_distance
from worker.solver.forces import ForceTerms
from worker.solver.methods.cheb_scvx.segments import Segments
from worker.solver.models.lift_vector import (
    SHARE_FLOOR,
    PlanetModel,
    lift_law,
    lift_vector_dynamics,
    polar_of,
)
from worker.solver.models.point_mass import PH, TH, R, V
from worker.solver.path_limits import path_values
from worker.solver.problem import EntryProblem

Array = np.ndarray


@dataclass
class ChebIterate:
    """A reference: states at the state points, lift vector at the control points, durations."""

    y: Array  # (P, 6) nondimensional
    u: Array  # (Q, 3)
    T: Array  # (S,) nondimensional segment durations


@dataclass
class PathLog:
    """ln(p / p_max) at the control points (Q, m) and its partials in r, V and u3."""

    names: tuple[str, ...]
    g: Array
    g_r: Array
    g_v: Array
    g_u3: Array


@dataclass
class ZoneLin:
    """One zone's distance (rad) at the state points followed by the between samples, with its
    partials in latitude and longitude."""

    c: Array
    c_lat: Array
    c_lon: Array


@dataclass
class ChebLinearization:
    """Everything the subproblem needs about one reference."""

    f: Array  # (Q, 6)
    A: Array  # (Q, 6, 6)
    B: Array  # (Q, 6, 3)
    defects: Array  # (P - 1, 6): the integral-form defects, interval-major (nondimensional)
    path: PathLog
    heat: Array  # (Q,) heat rate W/m^2 (zeros without a heating model)
    heat_r: Array
    heat_v: Array
    heat_u3: Array  # nonzero where a lift share sets the angle of a heating factor
    zones: list[ZoneLin]
    sample_y: Array  # (samples, 6) the reference between the points
    bank_rate: Array  # d sigma/dt at the control points and between samples (per nd time)


def defects(segments: Segments, it: ChebIterate, f: Array) -> Array:
    """y_i - y_0 - (T_s / 2) sum_k B_ik f_k at points i = 1..n_s of each interval (the integral
    form of paper 001 eq. 26: B the CGL integration matrix), interval-major, (sum n_s, 6).

    The differential form D y = (T/2) f at all n + 1 points of eq. 26 asks one condition too
    many per state: the values of f must lie on a polynomial of degree n - 1. Where the controls
    cannot steer f (above the atmosphere, or for r' = V gamma) that extra condition leaves a
    defect no step can remove; the integral form asks exactly n conditions per state."""
    out = np.empty((segments.state_points - 1, 6))
    row = 0
    for s, n in enumerate(segments.degrees):
        y = it.y[segments.states_of(s)]
        integral = segments.integration(s) @ f[segments.controls_of(s)]
        out[row : row + n] = y[1:] - y[0] - 0.5 * it.T[s] * integral[1:]
        row += n
    return out


def bank_rates(segments: Segments, u: Array, durations: Array) -> Array:
    """The flown bank's rate d sigma/dt = (u1 u2' - u2 u1') / (u1^2 + u2^2) at every control
    point and between sample (``Segments.rate_evaluation``, segment-major), the primes the
    derivatives of each interval's interpolating polynomials (what the verification flies:
    ``segments.LiftVectorPath``); per nondimensional time."""
    parts = []
    for s, (e, d) in enumerate(segments.rate_evaluation):
        ctrl = segments.controls_of(s)
        a, b = e @ u[ctrl, 0], e @ u[ctrl, 1]
        rho = np.maximum(a * a + b * b, RHO_FLOOR)
        parts.append((a * (d @ u[ctrl, 1]) - b * (d @ u[ctrl, 0])) / rho * (2.0 / durations[s]))
    return np.concatenate(parts)


RHO_FLOOR = 1.0e-6
"""Smallest |(u1, u2)|^2 the bank's rate is divided by (the bank is undefined at no lift)."""


def between_states(segments: Segments, y: Array) -> Array:
    """The interpolating polynomials' states at the between samples, segment-major."""
    parts = [w @ y[segments.states_of(s)] for s, (_, w) in enumerate(segments.between)]
    return np.concatenate(parts) if parts else np.zeros((0, 6))


@dataclass
class HeatRate:
    """The heat rate (W/m^2) at the control points with its partials in r, V and u3."""

    value: Array
    r: Array
    v: Array
    u3: Array


def path_log(problem: EntryProblem, y: Array, u: Array) -> tuple[PathLog, HeatRate]:
    """ln(p/p_max) of the active limits with partials in (r, V, u3), and the heat rate with its
    partials, at states ``y`` and lift vectors ``u``. The load factor is flown at
    lam = sqrt(u3) (an upper bound on |(u1, u2)| under the relaxation: the row is conservative);
    its u3 partial is taken in u3 itself, finite at lam = 0. A scheduled vehicle's limits are
    those of its schedule's full lift (u3 moves nothing). A lift share's heating factor
    qa(alpha) is taken at alpha(lam, M), with the partials of alpha in lam and the Mach number
    (the only place the lift share's own angle enters the path limits)."""
    forces = problem.forces
    law = lift_law(forces)
    polar = polar_of(forces)
    r, v = y[:, R], y[:, V]
    u3 = np.maximum(u[:, 2], 0.0)
    ft = forces.terms(r, v, None if law == "schedule" else np.sqrt(u3))
    heat_model = problem.heat_model
    angle: tuple[Array, Array] | None = None  # alpha's r and u3 partials where qa needs them
    if law == "share" and heat_model is not None and heat_model.alpha_polynomial:
        ft, *partials = _share_angle_terms(problem, r, v, u3, ft)
        angle = (partials[0], partials[1])
    rows = log_path_rows(problem, r, v, ft)
    pv = path_values(forces, heat_model, r, v, ft)
    heat = HeatRate(pv.heat_rate, pv.heat_rate_r, pv.heat_rate_v, np.zeros_like(r))
    g_u3 = np.zeros_like(rows.g)
    if heat_model is not None and angle is not None:
        alpha_r, alpha_u3 = angle
        qa, qa_a = heat_model.alpha_factor(ft.alpha_deg)
        factor = qa_a / qa  # d ln qa / d alpha
        heat.r = heat.r + heat.value * factor * alpha_r
        heat.u3 = heat.value * factor * alpha_u3
        if "heat_rate" in rows.names:
            j = rows.names.index("heat_rate")
            rows.g_r[:, j] += factor * alpha_r
            g_u3[:, j] = factor * alpha_u3
    if polar is not None and "load_factor" in rows.names:
        cls2 = polar.cl_star * polar.cl_star
        cd = polar.cd0 + polar.k_induced * cls2 * u3
        g_u3[:, rows.names.index("load_factor")] = (
            0.5 * (cls2 + 2.0 * cd * polar.k_induced * cls2) / (cls2 * u3 + cd * cd)
        )
    elif law == "share" and "load_factor" in rows.names:
        # d ln n / d u3 = (CL dCL/du3 + CD dCD/du3) / (CL^2 + CD^2), CL = lam CL_ref:
        # CL dCL/du3 = CL_ref^2 / 2, dCD/du3 = (dCD/dlam) / (2 lam)
        qk = np.maximum(forces.ballistic_factor * ft.rho * v * v, 1e-300)
        ref, cd_lam = ft.lift_a / qk, ft.drag_a / qk
        lam = np.maximum(np.sqrt(u3), SHARE_FLOOR)
        g_u3[:, rows.names.index("load_factor")] = (
            0.5 * ref * ref + 0.5 * ft.cd * cd_lam / lam
        ) / (ft.cl * ft.cl + ft.cd * ft.cd)
    return PathLog(rows.names, rows.g, rows.g_r, rows.g_v, g_u3), heat


def _share_angle_terms(
    problem: EntryProblem, r: Array, v: Array, u3: Array, ft: ForceTerms
) -> tuple[ForceTerms, Array, Array]:
    """``ft`` with the lift share's angle of attack alpha(lam, M) in place of lam and its speed
    partial (through the Mach number), and alpha's partials in r (through the Mach number) and
    in u3 = lam^2 (floored where lam is)."""
    aero = problem.forces.aero
    assert isinstance(aero, LiftShareAero)
    sc = problem.scales
    sound, sound_h = problem.forces.atmosphere.speed_of_sound((r - 1.0) * sc.radius_m)
    v_dim = v * sc.speed_m_s
    mach = v_dim / sound
    lam = np.maximum(np.sqrt(u3), SHARE_FLOOR)
    share = aero.alpha_partials(lam, mach)
    mach_v = sc.speed_m_s / sound
    mach_r = -v_dim / (sound * sound) * sound_h * sc.radius_m
    alpha_v = share.alpha_mach * mach_v
    moved = replace(ft, alpha_deg=share.alpha_deg, alpha_v=alpha_v)
    return moved, share.alpha_mach * mach_r, share.alpha_lam / (2.0 * lam)


def linearize(
    problem: EntryProblem, segments: Segments, it: ChebIterate, model: PlanetModel
) -> ChebLinearization:
    """The linearization about ``it`` at its control points."""
    ys = it.y[segments.state_of_control]
    d = lift_vector_dynamics(ys, it.u, problem.forces, problem.omega, model)
    assert d.A is not None and d.B is not None
    path, heat = path_log(problem, ys, it.u)
    sample_y = between_states(segments, it.y)
    every = np.vstack([it.y, sample_y])
    zones = []
    for zone in problem.no_fly_zones:
        z = zone_distance(every[:, PH], every[:, TH], zone)
        zones.append(ZoneLin(z.c, z.c_lat, z.c_lon))
    rates = (
        bank_rates(segments, it.u, it.T)
        if problem.bank_rate_max is not None
        else np.zeros(segments.rate_rows)
    )
    return ChebLinearization(
        d.f, d.A, d.B, defects(segments, it, d.f), path, heat.value, heat.r, heat.v, heat.u3,
        zones, sample_y, rates,
    )  # fmt: skip
