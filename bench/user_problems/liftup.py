"""The full-lift-up flight of a problem: its heat-rate, dynamic-pressure and load-factor peaks.

Bank zero from the entry state down to the terminal altitude, the angle of attack on its law (an
optimized one held at ``NOMINAL_ALPHA_DEG`` within its bounds, a polar at its largest lift):
the flight that keeps the vehicle highest for its speed, so the least stagnation heating an
entry can have to first order (paper 000 sec. 2's quasi-equilibrium argument). The generator sets
limits relative to these peaks; a heat limit well below the lift-up peak is a cheap physical
sign of infeasibility, recorded as such (not a proof). Non-rotating point mass (paper 000
eq. 1 with omega = 0), RK4 at 2 s, plain Python (a generator's step, not a reference).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

NOMINAL_ALPHA_DEG = 40.0
"""Angle of attack of the lift-up flight when the document optimizes it (clipped to its bounds)."""


def _horner(coefficients: list[float], x: float) -> float:
    """sum_k c_k x^k, lowest first."""
    value = 0.0
    for c in reversed(coefficients):
        value = value * x + c
    return value


def _density(atmosphere: dict[str, Any]) -> Any:
    """rho(h) of the document's atmosphere (numpy)."""
    if atmosphere.get("model", "exponential") == "exponential":
        rho0 = float(atmosphere.get("density_sea_level_kg_m3", 1.225))
        scale = float(atmosphere["scale_height_m"])
        return lambda h: rho0 * math.exp(-h / scale)
    from bench.nlp_models import us76_log_density

    z, log_rho = us76_log_density()
    step = float(z[1] - z[0])

    def rho(h: float) -> float:
        i = min(max(int(h // step), 0), z.size - 2)
        w = (h - z[i]) / step
        return math.exp((1.0 - w) * log_rho[i] + w * log_rho[i + 1])

    return rho


def _coefficients(vehicle: dict[str, Any]) -> Any:
    """(CL, CD) of speed (m/s) on the lift-up attitude."""
    aero = vehicle["aerodynamics"]
    if aero.get("model") == "parabolic_polar":
        cl = float(aero["cl_star"]) * float(aero.get("lambda_max", 1.0))
        cd = float(aero["cd0"]) + float(aero["k_induced"]) * cl * cl
        return lambda v: (cl, cd)
    attack = vehicle["angle_of_attack"]
    mode = attack["mode"]

    def alpha(v: float) -> float:
        if mode == "optimized":
            return min(max(NOMINAL_ALPHA_DEG, float(attack["min_deg"])), float(attack["max_deg"]))
        if mode == "constant":
            return float(attack["alpha_deg"])
        if mode == "table":
            return float(np.interp(v, attack["velocity_m_s"], attack["alpha_deg"]))
        a_max = float(attack.get("alpha_max_deg", 40.0))
        v_b = float(attack.get("velocity_break_m_s", 4570.0))
        k = (
            float(attack.get("slope_coefficient", 0.20705))
            / float(attack.get("velocity_scale_m_s", 340.0)) ** 2
        )
        return a_max if v > v_b else a_max - k * (v - v_b) ** 2

    cl_c = [float(c) for c in aero["cl_coefficients"]]
    cd_c = [float(c) for c in aero["cd_coefficients"]]
    by_cl = aero.get("cd_argument", "alpha") == "cl"

    def of(v: float) -> tuple[float, float]:
        a = alpha(v)
        cl = _horner(cl_c, a)
        return cl, _horner(cd_c, cl if by_cl else a)

    return of, alpha


def lift_up_peaks(document: dict[str, Any], bank_deg: float = 0.0) -> dict[str, float]:
    """Peaks of heat rate (W/m^2), dynamic pressure (Pa) and load factor (g) of the lift-up
    flight, and the speed (m/s; 0 if it skips out), time (s) and ground range (km) at which it
    reaches the terminal altitude. With ``bank_deg`` the lift is tilted that far (the vertical
    plane only): at the bank limit, the shortest track a flight without lift down has."""
    planet, vehicle = document["planet"], document["vehicle"]
    radius = float(planet.get("radius_m", 6378140.0))
    g0 = float(planet.get("g0_m_s2", 9.81))
    rho_of = _density(planet["atmosphere"])
    made = _coefficients(vehicle)
    coeffs, alpha_of = made if isinstance(made, tuple) else (made, None)
    s_over_m = float(vehicle["reference_area_m2"]) / float(vehicle["mass_kg"])
    vertical = math.cos(math.radians(bank_deg))
    heat = (document.get("path_constraints") or {}).get("heat_rate") or {}
    k_q = float(heat.get("k_q", 9.4369e-5))
    m_exp = float(heat.get("velocity_exponent", 3.15))
    n_exp = float(heat.get("density_exponent", 0.5))
    poly = [float(c) for c in heat.get("alpha_polynomial") or []]
    init = document["initial_state"]
    terminal = document["terminal"]["altitude_m"]
    h_end = float(terminal if isinstance(terminal, int | float) else terminal.get("value", 25e3))

    def rates(s: tuple[float, float, float]) -> tuple[float, float, float]:
        h, v, gam = s
        r = radius + h
        cl, cd = coeffs(v)
        q = 0.5 * rho_of(h) * v * v
        g = g0 * (radius / r) ** 2
        lift, drag = q * s_over_m * cl, q * s_over_m * cd
        return (
            v * math.sin(gam),
            -drag - g * math.sin(gam),
            (lift * vertical - (g - v * v / r) * math.cos(gam)) / v,
        )

    s = (
        float(init["altitude_m"]),
        float(init["velocity_m_s"]),
        math.radians(float(init["flight_path_angle_deg"])),
    )
    peaks = {
        "heat_rate": 0.0,
        "dynamic_pressure": 0.0,
        "load_factor": 0.0,
        "speed_at_end": 0.0,
        "time_at_end_s": 0.0,
        "range_at_end_km": 0.0,
    }
    dt = 2.0
    for step in range(10000):
        h, v, gam = s
        peaks["time_at_end_s"] = step * dt
        peaks["range_at_end_km"] += v * math.cos(gam) * radius / (radius + h) * dt / 1e3
        rho = rho_of(h)
        cl, cd = coeffs(v)
        qa = _horner(poly, alpha_of(v)) if poly and alpha_of else 1.0
        q = 0.5 * rho * v * v
        peaks["heat_rate"] = max(peaks["heat_rate"], k_q * rho**n_exp * v**m_exp * qa)
        peaks["dynamic_pressure"] = max(peaks["dynamic_pressure"], q)
        peaks["load_factor"] = max(peaks["load_factor"], q * s_over_m * math.hypot(cl, cd) / g0)
        if h <= h_end:
            peaks["speed_at_end"] = float(v)
            break
        if h > float(init["altitude_m"]) + 50e3 or v < 100.0:
            break
        k1 = rates(s)
        k2 = rates(tuple(a + 0.5 * dt * b for a, b in zip(s, k1, strict=True)))  # type: ignore[arg-type]
        k3 = rates(tuple(a + 0.5 * dt * b for a, b in zip(s, k2, strict=True)))  # type: ignore[arg-type]
        k4 = rates(tuple(a + dt * b for a, b in zip(s, k3, strict=True)))  # type: ignore[arg-type]
        s = tuple(
            a + dt / 6.0 * (b1 + 2 * b2 + 2 * b3 + b4)
            for a, b1, b2, b3, b4 in zip(s, k1, k2, k3, k4, strict=True)
        )  # type: ignore[assignment]
    return peaks


def state_loads(
    document: dict[str, Any], altitude_m: float, speed_m_s: float
) -> tuple[float, float]:
    """Dynamic pressure (Pa) and load factor (g) at one altitude and speed on the lift-up
    attitude: what a terminal condition itself imposes on the limits."""
    planet, vehicle = document["planet"], document["vehicle"]
    made = _coefficients(vehicle)
    coeffs = made[0] if isinstance(made, tuple) else made
    cl, cd = coeffs(speed_m_s)
    q = 0.5 * _density(planet["atmosphere"])(altitude_m) * speed_m_s**2
    s_over_m = float(vehicle["reference_area_m2"]) / float(vehicle["mass_kg"])
    return q, q * s_over_m * math.hypot(cl, cd) / float(planet.get("g0_m_s2", 9.81))
