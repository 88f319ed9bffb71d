"""Physical bounds of the problem contract: ranges that no real vehicle, planet or flight leaves.

They are generous (a gram-sized probe to a ten-thousand-tonne vehicle, an asteroid to a star,
meteor speeds) and exist so that a schema-valid document cannot carry absurd magnitudes such as
a mass of 1e308 kg into the solver's arithmetic: each bound is a 422 naming the field.
"""

from __future__ import annotations

from typing import Final

from pydantic import AfterValidator
from pydantic_core import PydanticCustomError

MASS_KG: Final = (1e-3, 1e7)
"""Vehicle mass, kg: from a 1 g probe to 10 000 t."""
REFERENCE_AREA_M2: Final = (1e-6, 1e4)
"""Aerodynamic reference area, m^2: from 1 mm^2 to 1 hectare."""
AERO_COEFFICIENT_MAX: Final = 1e3
"""Largest magnitude of a lift or drag coefficient, a polynomial coefficient or a table entry."""
MACH_MAX: Final = 1e3
"""Largest Mach number of an aerodynamic table."""
SPEED_MAX_M_S: Final = 1e5
"""Fastest planet-relative speed, m/s (meteors reach 72 km/s)."""
ALTITUDE_MAX_M: Final = 1e7
"""Highest altitude above the reference sphere, m (10 000 km)."""
TIME_MAX_S: Final = 1e7
"""Largest magnitude of a time, s (about 116 days)."""
RADIUS_M: Final = (1e3, 1e9)
"""Planet radius, m: from a 1 km asteroid to a star."""
SURFACE_GRAVITY_M_S2: Final = (1e-4, 1e3)
"""Gravitational acceleration at the reference radius, m/s^2 (given or mu / R0^2)."""
MU_MAX_M3_S2: Final = 1e21
"""Largest gravitational parameter, m^3/s^2 (the Sun's is 1.33e20)."""
ROTATION_RATE_MAX_RAD_S: Final = 1e-2
"""Fastest planet rotation, rad/s (a 10-minute day)."""
DENSITY_MAX_KG_M3: Final = 1e3
"""Densest atmosphere at zero altitude, kg/m^3 (Venus: 65)."""
SCALE_HEIGHT_M: Final = (10.0, 1e6)
"""Density scale height of an exponential atmosphere, m."""
SPEED_OF_SOUND_M_S: Final = (1.0, 1e4)
"""Speed of sound of an exponential atmosphere, m/s."""
HEAT_RATE_MAX_W_M2: Final = 1e10
"""Largest heat rate limit, W/m^2 (the Galileo probe met 3e8)."""
HEATING_CONSTANT_MAX: Final = 1e3
"""Largest heating constant k_q (SI)."""
EXPONENT_MAX: Final = 10.0
"""Largest exponent of the heat rate formula."""
DYNAMIC_PRESSURE_MAX_PA: Final = 1e8
"""Largest dynamic pressure limit, Pa."""
LOAD_FACTOR_MAX_G: Final = 1e4
"""Largest load factor limit, in g0."""
ANGLE_RATE_MAX_DEG_S: Final = 1e4
"""Largest bound on a bank or angle-of-attack rate, deg/s."""
WEIGHT_MAX: Final = 1e12
"""Largest weight of an objective term, a soft target or a method's penalty."""
ENERGY_MAX: Final = 1e6
"""Largest magnitude of a nondimensional energy bound."""
THRUST_MAX_N: Final = 1e8
"""Largest thrust, N (the Saturn V's first stage gave 3.5e7)."""
SPECIFIC_IMPULSE_S: Final = (1.0, 1e5)
"""Specific impulse, s: from below a cold-gas thruster's (about 70 s) to past an ion engine's."""
THRUST_LAG_MIN_S: Final = 1e-3
"""Shortest positive time constant of a thrust lag, s (0 means no lag)."""


def minimum(low: float) -> AfterValidator:
    """Annotation for a positive quantity (``gt=0`` stays its own check) that must also be at
    least ``low``: a 422 ``below_minimum`` naming the bound."""

    def check(value: float) -> float:
        if value < low:
            raise PydanticCustomError(
                "below_minimum",
                "Input should be at least {low} (smaller values are not physical)",
                {"low": f"{low:g}"},
            )
        return value

    return AfterValidator(check)
