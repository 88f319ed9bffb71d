"""The NLP transcription's force models, written from the contract (app/schemas) in CasADi.

Atmospheres (exponential; U.S. Standard Atmosphere 1976 from the ``ussa1976`` package, log
density as a cubic B-spline of geometric altitude), polynomial aerodynamics (CL in alpha, CD in
alpha or in CL, any degree) and a parabolic polar, the angle-of-attack laws (velocity schedule of
paper 000 eq. 9, table, constant), and the heat rate k_q rho^n V^m qa(alpha) (paper 000 eq. 12,
paper 004's alpha factor). Written independently of ``worker.solver`` so that the benchmark's
reference checks the service's model rather than repeating it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import lru_cache
from typing import Any

import numpy as np

US76_TOP_M = 300e3
"""Highest altitude of the U.S. 1976 spline, m (an entry starts at 80-125 km)."""
US76_STEP_M = 200.0
"""Spacing of the U.S. 1976 spline's nodes, m: log(rho) within 2e-4 of the standard's."""


def horner(ca: Any, coefficients: Sequence[float], x: Any) -> Any:
    """sum_k c_k x^k, lowest first."""
    value: Any = 0.0
    for c in reversed(coefficients):
        value = value * x + float(c)
    return value


@lru_cache(maxsize=1)
def us76_log_density() -> tuple[np.ndarray, np.ndarray]:
    """Altitudes (m) and log(rho) of the standard on the spline's nodes (cached)."""
    import ussa1976

    z = np.arange(0.0, US76_TOP_M + US76_STEP_M / 2, US76_STEP_M)
    rho = np.asarray(ussa1976.compute(z, variables=["rho"])["rho"].values, dtype=float)
    return z, np.log(rho)


def density(ca: Any, atmosphere: dict[str, Any]) -> Callable[[Any], Any]:
    """rho(h) in kg/m^3 of altitude h in metres, for the atmosphere of the document."""
    model = atmosphere.get("model", "exponential")
    if model == "exponential":
        rho0 = float(atmosphere.get("density_sea_level_kg_m3", 1.225))
        scale = float(atmosphere["scale_height_m"])
        return lambda h: rho0 * ca.exp(-h / scale)
    if model == "us76":
        z, log_rho = us76_log_density()
        spline = ca.interpolant("us76_log_rho", "bspline", [z], log_rho)
        return lambda h: ca.exp(spline(h))
    raise ValueError(f"the NLP transcription has no atmosphere {model!r}")


def alpha_law(ca: Any, attack: dict[str, Any]) -> Callable[[Any], Any] | None:
    """alpha (deg) of speed (m/s) for a scheduled, tabulated or constant angle of attack; None
    when it is optimized."""
    mode = attack.get("mode", "velocity_schedule")
    if mode == "velocity_schedule":  # paper 000 eq. 9
        a_max = float(attack.get("alpha_max_deg", 40.0))
        v_break = float(attack.get("velocity_break_m_s", 4570.0))
        k = (
            float(attack.get("slope_coefficient", 0.20705))
            / float(attack.get("velocity_scale_m_s", 340.0)) ** 2
        )
        return lambda v: ca.if_else(v > v_break, a_max, a_max - k * (v - v_break) ** 2)
    if mode == "table":
        speeds = [float(s) for s in attack["velocity_m_s"]]
        alphas = [float(a) for a in attack["alpha_deg"]]
        table = ca.interpolant("alpha_table", "linear", [speeds], alphas)
        return lambda v: table(ca.fmin(ca.fmax(v, speeds[0]), speeds[-1]))
    if mode == "constant":
        value = float(attack["alpha_deg"])
        return lambda v: value + 0.0 * v
    if mode == "optimized":
        return None
    raise ValueError(f"the NLP transcription has no angle-of-attack mode {mode!r}")


def coefficients(ca: Any, aero: dict[str, Any]) -> Callable[[Any], tuple[Any, Any]]:
    """(CL, CD) of the attitude variable: alpha in degrees for polynomials, the normalized lift
    lambda for a parabolic polar (paper 001: CL = lambda CL*, CD = CD0 + k CL^2)."""
    model = aero.get("model", "polynomial")
    if model == "parabolic_polar":
        cl_star, cd0, k = float(aero["cl_star"]), float(aero["cd0"]), float(aero["k_induced"])
        return lambda lam: (lam * cl_star, cd0 + k * (lam * cl_star) ** 2)
    if model != "polynomial":
        raise ValueError(f"the NLP transcription has no aerodynamic model {model!r}")
    cl_c = [float(c) for c in aero["cl_coefficients"]]
    cd_c = [float(c) for c in aero["cd_coefficients"]]
    by_cl = aero.get("cd_argument", "alpha") == "cl"

    def of(alpha_deg: Any) -> tuple[Any, Any]:
        cl = horner(ca, cl_c, alpha_deg)
        return cl, horner(ca, cd_c, cl if by_cl else alpha_deg)

    return of


def heat_rate(heat: dict[str, Any]) -> Callable[[Any, Any, Any], Any]:
    """Qdot (W/m^2) of density (kg/m^3), speed (m/s) and alpha (deg): k_q rho^n V^m qa(alpha)."""
    k_q = float(heat.get("k_q", 0.0))
    m = float(heat.get("velocity_exponent", 3.15))
    n = float(heat.get("density_exponent", 0.5))
    poly = [float(c) for c in heat.get("alpha_polynomial") or []]

    def of(rho: Any, v: Any, alpha_deg: Any) -> Any:
        qa = horner(None, poly, alpha_deg) if poly and alpha_deg is not None else 1.0
        return k_q * rho**n * v**m * qa

    return of
