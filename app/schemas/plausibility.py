"""Plausibility warnings: legal values of a problem far outside what entry vehicles fly.

A valid document may still carry a slip of units (a speed in km/s, a mass in tonnes, a limit in
kW/m^2), which the solver would meet only as a start it cannot make or a limit it cannot hold.
Each finding is a warning naming the field, its value, the plausible range and a sentence;
nothing is refused. The ranges reach well past the extremes of flown vehicles (their sources:
docs/problem-contract.md, "Plausibility warnings"); they are Earth figures except the entry
speed's upper bound, which follows the document's planet.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

from pydantic import Field

from app.schemas.aerodynamics import Aerodynamics
from app.schemas.base import StrictModel
from app.schemas.constraints import PathConstraints
from app.schemas.problem import ProblemDocument
from app.schemas.vehicle import AngleOfAttack

ENTRY_SPEED_MIN_M_S = 1_000.0
"""Slowest plausible entry speed: entries start hypersonic (the built-in ones at 7.3-7.8 km/s)
and entry guidance ends near here (the Shuttle's at 762 m/s)."""
HYPERBOLIC_EXCESS_M_S = 7_000.0
"""Largest speed beyond the planet's escape speed at the entry point (Stardust's 12.9 km/s at
Earth, about 6.4 km/s beyond it, the fastest flown)."""
ENTRY_ALTITUDE_M = (20_000.0, 300_000.0)
"""Plausible initial altitude (Earth's entry interface is 121.9 km; the built-in problems start
at 79-122 km)."""
MASS_KG = (10.0, 2.0e5)
"""Plausible vehicle mass (the 17 kg Hayabusa capsule to twice the Shuttle orbiter)."""
REFERENCE_AREA_M2 = (0.05, 1.0e3)
"""Plausible reference area (Hayabusa's 0.13 m^2 to 2.5 x the 391 m^2 RLV model)."""
BALLISTIC_COEFFICIENT_KG_M2 = (10.0, 3.0e4)
"""Plausible m / (CD S) (inflatable decelerators to twice the CAV-H glider's 14 500 kg/m^2)."""
HEAT_RATE_LIMIT_W_M2 = (1.0e4, 3.0e7)
"""Plausible heat-rate limit (1/80 of the Shuttle's to 2.5 x Stardust's 12 MW/m^2 peak)."""
DYNAMIC_PRESSURE_LIMIT_PA = (1.0e3, 2.0e6)
"""Plausible dynamic-pressure limit (1/16 of the Shuttle's 16 kPa to 4 x CAV-H's 500 kPa)."""
LOAD_FACTOR_LIMIT_G = (1.0, 50.0)
"""Plausible load-factor limit (a glide slowing down needs lift near its weight, 1 g; capsules
of sample returns fly tens of g)."""
HYPERSONIC_ALPHA_DEG = 40.0
"""Angle of attack of the ballistic coefficient for an optimized attitude: the hypersonic
attitude of the Shuttle, the X-33 and the RLV models."""


class PlausibilityWarning(StrictModel):
    """A legal value far outside what entry vehicles fly: likely a slip of units."""

    field: str = Field(..., description="Dotted path of the field (vehicle: its mass, drag, area).")
    quantity: str = Field(..., description="What the value is.")
    value: float = Field(..., description="The value, in unit.")
    unit: str = Field(..., description="The unit of value and of the plausible range.")
    plausible_min: float = Field(..., description="Lower end of the plausible range.")
    plausible_max: float = Field(..., description="Upper end of the plausible range.")
    message: str = Field(..., description="What is implausible, and the likely slip.")


_THOUSANDS = {"m/s": "km/s", "m": "km", "kg": "tonnes", "W/m^2": "kW/m^2", "Pa": "kPa"}
"""Units whose thousandfold a value below its range was likely given in."""


def _check(
    field: str,
    quantity: str,
    value: float,
    unit: str,
    plausible: tuple[float, float],
    note: str = "",
    slip: str | None = None,
) -> Iterator[PlausibilityWarning]:
    """A warning when ``value`` lies outside ``plausible`` (nothing otherwise); below it, and
    in range a thousandfold, ``slip`` names the likely slip (by default a unit's thousandfold)."""
    low, high = plausible
    if low <= value <= high:
        return
    side = "below" if value < low else "above"
    hint = ""
    bigger = _THOUSANDS.get(unit)
    if slip is None and bigger is not None:
        slip = f"was it given in {bigger}?"
    if slip is not None and value < low and low <= 1000.0 * value <= high:
        hint = f"; {slip}"
    yield PlausibilityWarning(
        field=field,
        quantity=quantity,
        value=value,
        unit=unit,
        plausible_min=low,
        plausible_max=high,
        message=f"{field}: {quantity} {value:.4g} {unit}{note} is far {side} what entry "
        f"vehicles fly ({low:.6g} to {high:.6g} {unit}){hint}",
    )


def entry_speed_max_m_s(doc: ProblemDocument) -> float:
    """Fastest plausible entry speed at the document's planet: its escape speed at the initial
    altitude combined with the largest hyperbolic excess (13.1 km/s at Earth from 100 km)."""
    planet = doc.planet
    radius = planet.radius_m + doc.initial_state.altitude_m
    escape_sq = 2.0 * planet.surface_gravity_m_s2 * planet.radius_m**2 / radius
    return math.sqrt(escape_sq + HYPERBOLIC_EXCESS_M_S**2)


def _polynomial(coefficients: Sequence[float], x: float) -> float:
    return sum(c * x**k for k, c in enumerate(coefficients))


def representative_alpha_deg(doc: ProblemDocument) -> float | None:
    """The angle of attack of the hypersonic entry (None for a polar vehicle, which has none):
    a schedule's top value, a speed table's fastest entry, a constant, or an optimized
    attitude's initial value (else 40 deg within its bounds)."""
    alpha: AngleOfAttack | None = doc.vehicle.angle_of_attack
    if alpha is None:
        return None
    if alpha.mode == "velocity_schedule":
        return alpha.alpha_max_deg
    if alpha.mode == "table":
        return alpha.alpha_deg[-1]
    if alpha.mode == "constant":
        return alpha.alpha_deg
    given = doc.initial_state.alpha_deg
    given = alpha.initial_deg if given is None else given
    if given is not None:
        return given
    return min(max(HYPERSONIC_ALPHA_DEG, alpha.min_deg), alpha.max_deg)


def drag_coefficient(aero: Aerodynamics, alpha_deg: float | None) -> tuple[float, str] | None:
    """CD at the representative attitude and where it was read; None without an attitude for
    a model that needs one. A table is read at its highest Mach number (hypersonic)."""
    if aero.model == "parabolic_polar":
        return aero.cd0 + aero.k_induced * aero.cl_star**2, "at its design lift (lambda 1)"
    if alpha_deg is None:
        return None
    where = f"at alpha {alpha_deg:.3g} deg"
    if aero.model == "polynomial":
        cl = _polynomial(aero.cl_coefficients, alpha_deg)
        x = alpha_deg if aero.cd_argument == "alpha" else cl
        return _polynomial(aero.cd_coefficients, x), where
    column = [row[-1] for row in aero.cd]
    return _interpolate(aero.alpha_deg, column, alpha_deg), f"{where}, Mach {aero.mach[-1]:g}"


def _interpolate(xs: Sequence[float], ys: Sequence[float], x: float) -> float:
    """Piecewise-linear ``ys`` at ``x`` (held at the ends)."""
    if x <= xs[0]:
        return ys[0]
    for i in range(1, len(xs)):
        if x <= xs[i]:
            share = (x - xs[i - 1]) / (xs[i] - xs[i - 1])
            return ys[i - 1] + share * (ys[i] - ys[i - 1])
    return ys[-1]


def _ballistic(doc: ProblemDocument) -> Iterator[PlausibilityWarning]:
    """The ballistic coefficient m / (CD S) at the representative attitude (none when CD is
    not positive there: the coefficient is then not defined)."""
    vehicle = doc.vehicle
    found = drag_coefficient(vehicle.aerodynamics, representative_alpha_deg(doc))
    if found is None or not found[0] > 0.0:
        return
    cd, where = found
    beta = vehicle.mass_kg / (cd * vehicle.reference_area_m2)
    note = (
        f" (vehicle.mass_kg {vehicle.mass_kg:.4g} kg over CD {cd:.3g} {where} times "
        f"vehicle.reference_area_m2 {vehicle.reference_area_m2:.4g} m^2)"
    )
    yield from _check(
        "vehicle",
        "ballistic coefficient m/(CD S)",
        beta,
        "kg/m^2",
        BALLISTIC_COEFFICIENT_KG_M2,
        note,
        "is the mass in tonnes?",
    )


def _limits(prefix: str, limits: PathConstraints) -> Iterator[PlausibilityWarning]:
    if limits.heat_rate is not None:
        yield from _check(
            f"{prefix}.heat_rate.max_W_m2",
            "heat-rate limit",
            limits.heat_rate.max_W_m2,
            "W/m^2",
            HEAT_RATE_LIMIT_W_M2,
        )
    if limits.dynamic_pressure is not None:
        yield from _check(
            f"{prefix}.dynamic_pressure.max_Pa",
            "dynamic-pressure limit",
            limits.dynamic_pressure.max_Pa,
            "Pa",
            DYNAMIC_PRESSURE_LIMIT_PA,
        )
    if limits.load_factor is not None:
        yield from _check(
            f"{prefix}.load_factor.max_g",
            "load-factor limit",
            limits.load_factor.max_g,
            "g",
            LOAD_FACTOR_LIMIT_G,
        )


def plausibility_warnings(doc: ProblemDocument) -> list[PlausibilityWarning]:
    """Every legal value of ``doc`` far outside what entry vehicles fly, in document order."""
    state, vehicle = doc.initial_state, doc.vehicle
    speed = (ENTRY_SPEED_MIN_M_S, round(entry_speed_max_m_s(doc), -2))
    found = [
        *_check("initial_state.velocity_m_s", "entry speed", state.velocity_m_s, "m/s", speed),
        *_check(
            "initial_state.altitude_m", "entry altitude", state.altitude_m, "m", ENTRY_ALTITUDE_M
        ),
        *_check("vehicle.mass_kg", "vehicle mass", vehicle.mass_kg, "kg", MASS_KG),
        *_check(
            "vehicle.reference_area_m2",
            "reference area",
            vehicle.reference_area_m2,
            "m^2",
            REFERENCE_AREA_M2,
        ),
        *_ballistic(doc),
        *_limits("path_constraints", doc.path_constraints),
    ]
    for i, phase in enumerate(doc.phases):
        if phase.path_constraints is not None:
            found.extend(_limits(f"phases[{i}].path_constraints", phase.path_constraints))
    return found
