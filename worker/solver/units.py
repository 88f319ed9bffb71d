"""Nondimensional units of the entry problem: length R0, speed sqrt(R0 g0), time sqrt(R0/g0)."""

from __future__ import annotations

import math
from dataclasses import dataclass

COLUMN_UNITS = {
    "time_s": "s",
    "altitude_m": "m",
    "longitude_deg": "deg",
    "latitude_deg": "deg",
    "velocity_m_s": "m/s",
    "flight_path_angle_deg": "deg",
    "heading_deg": "deg",
    "bank_deg": "deg",
    "alpha_deg": "deg",
    "normalized_lift": "1",
    "heat_rate_W_m2": "W/m^2",
    "dynamic_pressure_Pa": "Pa",
    "load_factor_g": "g0",
    "energy": "1 (e = R0/r - V^2/(2 g0 R0))",
    "mass_kg": "kg",
    "thrust_n": "N",
    "thrust_command_n": "N",
    "phase": "1",
}
"""The unit of each named column of a trajectory (optimized nodes or the propagated flight)."""


@dataclass(frozen=True)
class Scales:
    """Reference scales used by every formulation (paper 000 sec. 2.1, the usual Vinh/Lu choice)."""

    radius_m: float
    g0_m_s2: float

    @property
    def length_m(self) -> float:
        return self.radius_m

    @property
    def speed_m_s(self) -> float:
        return math.sqrt(self.radius_m * self.g0_m_s2)

    @property
    def time_s(self) -> float:
        return math.sqrt(self.radius_m / self.g0_m_s2)

    @property
    def rate_rad_s(self) -> float:
        """Angular rate scale sqrt(g0/R0), used for the planet's rotation rate."""
        return math.sqrt(self.g0_m_s2 / self.radius_m)

    def energy(self, radius_nd: float, speed_nd: float) -> float:
        """Energy-like variable e = 1/r - V^2/2 (paper 000 eq. 7), nondimensional."""
        return 1.0 / radius_nd - 0.5 * speed_nd * speed_nd
