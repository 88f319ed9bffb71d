"""Aerodynamic forces and path quantities with their partials in (r, V, alpha).

Everything nondimensional (units.Scales) except the path quantities, which are returned in SI
(W/m^2, Pa, g) because their limits are given in SI. Vectorized over nodes and complex-safe
(for complex-step tests) when the atmosphere and aerodynamic models are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worker.solver.aero_models import AeroModel
from worker.solver.alpha_schedules import AlphaSchedule
from worker.solver.atmosphere import Atmosphere
from worker.solver.units import Scales

Array = np.ndarray


@dataclass
class ForceTerms:
    """Lift and drag accelerations (in g0) and their partials; alpha in degrees.

    The ``*_v`` partials include the angle-of-attack schedule's dependence on speed when alpha
    is scheduled; ``*_a`` are the partials in alpha when alpha is a decision variable.
    """

    lift: Array
    drag: Array
    lift_r: Array
    lift_v: Array
    lift_a: Array
    drag_r: Array
    drag_v: Array
    drag_a: Array
    alpha_deg: Array
    alpha_v: Array
    rho: Array
    rho_r: Array
    cl: Array
    cd: Array


@dataclass(frozen=True)
class VehicleForces:
    """Evaluates L, D of a vehicle in an atmosphere, nondimensionalized by ``scales``."""

    scales: Scales
    mass_kg: float
    area_m2: float
    atmosphere: Atmosphere
    aero: AeroModel
    alpha_schedule: AlphaSchedule | None

    @property
    def ballistic_factor(self) -> float:
        """R0 S / (2 m): L = factor * rho V^2 CL with V nondimensional (paper 000 eq. 2-3)."""
        return self.scales.radius_m * self.area_m2 / (2.0 * self.mass_kg)

    def alpha(self, v_nd: Array, alpha_deg: Array | None = None) -> tuple[Array, Array]:
        """Angle of attack (deg) and its derivative in nondimensional speed."""
        if alpha_deg is not None:
            return alpha_deg, np.zeros_like(v_nd)
        if self.alpha_schedule is None:
            raise ValueError("angle of attack is optimized: pass alpha_deg explicitly")
        a, da_dv = self.alpha_schedule.alpha_deg(v_nd * self.scales.speed_m_s)
        return a, da_dv * self.scales.speed_m_s

    def lift_drag(self, r_nd: Array, v_nd: Array) -> tuple[Array, Array, Array, Array]:
        """rho (kg/m^3), lift, drag (in g0) and alpha (deg) on the schedule: ``terms`` values only.

        For callers that need no partials (the path-limit bisection); same arithmetic as ``terms``.
        """
        sc = self.scales
        h = (r_nd - 1.0) * sc.radius_m
        rho, _ = self.atmosphere.density(h)
        a_snd, _ = self.atmosphere.speed_of_sound(h)
        mach = v_nd * sc.speed_m_s / a_snd
        alpha, _ = self.alpha(v_nd)
        c = self.aero.coefficients(alpha, mach)
        qk = self.ballistic_factor * rho * v_nd * v_nd
        return rho, qk * c.cl, qk * c.cd, alpha

    def terms(self, r_nd: Array, v_nd: Array, alpha_deg: Array | None = None) -> ForceTerms:
        """L, D and partials at radius ``r_nd`` and speed ``v_nd`` (both nondimensional)."""
        sc = self.scales
        h = (r_nd - 1.0) * sc.radius_m
        rho, drho_dh = self.atmosphere.density(h)
        rho_r = drho_dh * sc.radius_m
        a_snd, da_dh = self.atmosphere.speed_of_sound(h)
        v_dim = v_nd * sc.speed_m_s
        mach = v_dim / a_snd
        mach_v = sc.speed_m_s / a_snd
        mach_r = -v_dim / (a_snd * a_snd) * da_dh * sc.radius_m
        alpha, alpha_v = self.alpha(v_nd, alpha_deg)
        c = self.aero.coefficients(alpha, mach)
        k = self.ballistic_factor
        qk = k * rho * v_nd * v_nd  # lift = qk * CL
        qk_r = k * rho_r * v_nd * v_nd
        qk_v = 2.0 * k * rho * v_nd
        cl_v = c.dcl_dalpha * alpha_v + c.dcl_dmach * mach_v
        cd_v = c.dcd_dalpha * alpha_v + c.dcd_dmach * mach_v
        return ForceTerms(
            lift=qk * c.cl,
            drag=qk * c.cd,
            lift_r=qk_r * c.cl + qk * c.dcl_dmach * mach_r,
            lift_v=qk_v * c.cl + qk * cl_v,
            lift_a=qk * c.dcl_dalpha,
            drag_r=qk_r * c.cd + qk * c.dcd_dmach * mach_r,
            drag_v=qk_v * c.cd + qk * cd_v,
            drag_a=qk * c.dcd_dalpha,
            alpha_deg=alpha,
            alpha_v=alpha_v,
            rho=rho,
            rho_r=rho_r,
            cl=c.cl,
            cd=c.cd,
        )
