"""The solver's problem model: the request document turned into nondimensional, typed parts.

This is the second stage of the data flow (request schema -> problem model -> transcription ->
SCP -> conic backend -> verification): everything downstream works in the units of
``units.Scales`` and never looks at the request document again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from app.schemas import ProblemDocument
from worker.solver.aerodynamics import aero_from_spec, alpha_schedule_from_spec
from worker.solver.atmosphere import atmosphere_from_spec
from worker.solver.forces import VehicleForces
from worker.solver.geometry import CircleZone
from worker.solver.guess_path import GuessPath
from worker.solver.path_limits import HeatRateModel, PathLimits
from worker.solver.trajectory import TIME_STATE_NAMES
from worker.solver.units import Scales

TerminalKind = Literal["fixed", "range", "free", "soft"]


@dataclass(frozen=True)
class TerminalTarget:
    """One terminal condition in nondimensional units (radius for altitude, radians for angles)."""

    kind: TerminalKind
    value: float | None = None
    lo: float | None = None
    hi: float | None = None
    weight: float = 0.0

    def target(self) -> float | None:
        """The value aimed at: fixed or soft value, or a range's midpoint."""
        if self.kind in ("fixed", "soft"):
            return self.value
        if self.kind == "range" and self.lo is not None and self.hi is not None:
            return 0.5 * (self.lo + self.hi)
        return None


@dataclass(frozen=True)
class ObjectiveTerm:
    """A term of the objective: its name and weight."""

    name: str
    weight: float


@dataclass
class EntryProblem:
    """Nondimensional entry problem shared by every method: everything downstream reads of the
    request, as typed fields (the request document itself stays with the caller)."""

    name: str | None  # the problem's label, for the result's provenance
    scales: Scales
    forces: VehicleForces
    omega: float
    limits: PathLimits
    heat_model: HeatRateModel | None
    bank_max: float  # radians, the upper bound on the bank
    bank_min: float  # radians, the lower bound (-bank_max for a symmetric range)
    bank_rate_max: float | None
    y0: np.ndarray  # [r, theta, phi, V, gamma, psi] at the initial time
    initial_bank: float | None  # radians; None when the request leaves the initial bank free
    initial_bank_deg: float | None  # the same as the request gives it, for what reports degrees
    t0: float
    terminal: dict[str, TerminalTarget]  # keyed by TIME_STATE_NAMES
    terminal_si: dict[str, TerminalTarget]  # the same in the request's units (m, deg, m/s)
    final_time: float | None  # nondimensional, None when free
    energy_initial: float | None
    energy_final: float | None
    objective: list[ObjectiveTerm]
    no_fly_zones: list[CircleZone] = field(default_factory=list)
    waypoints: list[CircleZone] = field(default_factory=list)
    alpha_optimized: bool = False
    alpha_range: tuple[float, float] | None = None
    """Bounds of an optimized angle of attack (radians); None when it is scheduled."""
    alpha_rate_max: float | None = None
    """Bound on |d alpha/dt| of an optimized angle of attack (rad per nondimensional time)."""
    initial_alpha: float | None = None
    """Optimized angle of attack at the initial time (radians); None when free."""
    guess: GuessPath | None = None
    """The caller's initial guess (an earlier answer); None: the method's own guess."""
    lift_range: tuple[float, float] | None = None
    """A parabolic polar's normalized-lift range (lambda_min, lambda_max); None otherwise."""
    planet_model: Literal["spherical", "flat"] = "spherical"
    """The equations of motion: the spherical planet, or paper 001's flat-Earth model."""
    final_time_max: float | None = None
    """Latest final time of a free final time, nondimensional from the initial time."""

    def radius(self, altitude_m: float) -> float:
        """Nondimensional radius of an altitude in metres."""
        return 1.0 + altitude_m / self.scales.radius_m

    def altitude_m(self, radius_nd: np.ndarray) -> np.ndarray:
        """Altitudes in metres of nondimensional radii."""
        return (radius_nd - 1.0) * self.scales.radius_m


def _terminal_to_nd(spec: Any, to_nd: Any) -> TerminalTarget:
    """One terminal condition of the request turned nondimensional by ``to_nd``."""
    kind = spec.kind
    if kind == "fixed":
        return TerminalTarget("fixed", value=to_nd(spec.value))
    if kind == "range":
        return TerminalTarget("range", lo=to_nd(spec.lo), hi=to_nd(spec.hi))
    if kind == "soft":
        return TerminalTarget("soft", value=to_nd(spec.value), weight=float(spec.weight))
    return TerminalTarget("free")


def _terminal_as_given(spec: Any) -> TerminalTarget:
    """One terminal condition kept in the request's units, as the verification reports it."""
    if spec.kind == "fixed":
        return TerminalTarget("fixed", value=spec.value)
    if spec.kind == "range":
        return TerminalTarget("range", lo=spec.lo, hi=spec.hi)
    if spec.kind == "soft":
        return TerminalTarget("soft", value=spec.value, weight=float(spec.weight))
    return TerminalTarget("free")


def _zone_radius_rad(zone: Any, planet_radius_m: float) -> float:
    """A zone's radius as a central angle: given in degrees, or in km along the surface."""
    if getattr(zone, "radius_deg", None) is not None:
        return math.radians(zone.radius_deg)
    return float(zone.radius_km) * 1000.0 / planet_radius_m


def build_problem(doc: ProblemDocument) -> EntryProblem:
    """Turn a validated problem document into the solver's nondimensional model."""
    planet = doc.planet
    g0 = planet.surface_gravity_m_s2
    scales = Scales(radius_m=planet.radius_m, g0_m_s2=g0)
    vehicle = doc.vehicle
    spec = vehicle.angle_of_attack
    schedule = alpha_schedule_from_spec(spec) if spec is not None else None
    forces = VehicleForces(
        scales=scales,
        mass_kg=vehicle.mass_kg,
        area_m2=vehicle.reference_area_m2,
        atmosphere=atmosphere_from_spec(planet.atmosphere),
        aero=aero_from_spec(vehicle.aerodynamics),
        alpha_schedule=schedule,
    )
    omega = planet.rotation_rate_rad_s / scales.rate_rad_s if planet.rotation else 0.0

    limits = path_limits_from_spec(doc.path_constraints)
    heat_model = limits.heat

    s0 = doc.initial_state
    y0 = np.array(
        [
            1.0 + s0.altitude_m / scales.radius_m,
            math.radians(s0.longitude_deg),
            math.radians(s0.latitude_deg),
            s0.velocity_m_s / scales.speed_m_s,
            math.radians(s0.flight_path_angle_deg),
            math.radians(s0.heading_deg),
        ]
    )
    terminal, terminal_si = terminal_targets(doc.terminal, scales)
    final_time = None
    if doc.final_time.kind == "fixed":
        final_time = (doc.final_time.value_s - s0.time_s) / scales.time_s
    energy_initial = doc.energy.initial if doc.energy is not None else None
    energy_final = doc.energy.final if doc.energy is not None else None
    zones = [
        CircleZone(
            latitude=math.radians(z.center_latitude_deg),
            longitude=math.radians(z.center_longitude_deg),
            radius=_zone_radius_rad(z, planet.radius_m),
            name=z.name,
            metric=z.metric,
        )
        for z in doc.no_fly_zones
    ]
    waypoints = [
        CircleZone(
            latitude=math.radians(w.latitude_deg),
            longitude=math.radians(w.longitude_deg),
            radius=_zone_radius_rad(w, planet.radius_m),
            order=w.order,
            metric="lat_lon" if planet.model == "flat" else "great_circle",
        )
        for w in sorted(doc.waypoints, key=lambda w: w.order)
    ]
    return EntryProblem(
        name=doc.name,
        scales=scales,
        forces=forces,
        omega=omega,
        limits=limits,
        heat_model=heat_model,
        bank_max=math.radians(doc.control_limits.bank_max_deg),
        bank_min=math.radians(doc.control_limits.bank_lower_deg),
        bank_rate_max=(
            math.radians(doc.control_limits.bank_rate_max_deg_s) * scales.time_s
            if doc.control_limits.bank_rate_max_deg_s is not None
            else None
        ),
        y0=y0,
        initial_bank=math.radians(s0.bank_deg) if s0.bank_deg is not None else None,
        initial_bank_deg=s0.bank_deg,
        t0=s0.time_s,
        terminal=terminal,
        terminal_si=terminal_si,
        final_time=final_time,
        energy_initial=energy_initial,
        energy_final=energy_final,
        objective=[ObjectiveTerm(t.name, t.weight) for t in doc.objective.terms],
        no_fly_zones=zones,
        waypoints=waypoints,
        alpha_optimized=spec is not None and schedule is None,
        **_optimized_alpha(doc, scales),
        guess=_guess(doc, scales),
        lift_range=_lift_range(doc),
        planet_model=planet.model,
        final_time_max=(
            (doc.final_time.max_s - s0.time_s) / scales.time_s
            if doc.final_time.kind == "free" and doc.final_time.max_s is not None
            else None
        ),
    )


def terminal_targets(
    conditions: Any, scales: Scales
) -> tuple[dict[str, TerminalTarget], dict[str, TerminalTarget]]:
    """Conditions on a final state (the document's ``terminal`` or a phase's ``end``), keyed by
    ``TIME_STATE_NAMES``: nondimensional, and as given (SI and degrees)."""
    converters = {
        "altitude_m": lambda h: 1.0 + float(h) / scales.radius_m,
        "longitude_deg": lambda a: math.radians(float(a)),
        "latitude_deg": lambda a: math.radians(float(a)),
        "velocity_m_s": lambda v: float(v) / scales.speed_m_s,
        "flight_path_angle_deg": lambda a: math.radians(float(a)),
        "heading_deg": lambda a: math.radians(float(a)),
    }
    names = TIME_STATE_NAMES
    nd = {name: _terminal_to_nd(getattr(conditions, name), converters[name]) for name in names}
    si = {name: _terminal_as_given(getattr(conditions, name)) for name in names}
    return nd, si


def path_limits_from_spec(pc: Any) -> PathLimits:
    """The path limits of a document's (or a phase's) ``path_constraints``, SI."""
    heat_model = None
    if pc.heat_rate is not None:
        hr = pc.heat_rate
        heat_model = HeatRateModel(
            k_q=hr.k_q,
            velocity_exponent=hr.velocity_exponent,
            density_exponent=hr.density_exponent,
            alpha_polynomial=tuple(hr.alpha_polynomial) if hr.alpha_polynomial else None,
        )
    return PathLimits(
        heat=heat_model,
        heat_max_W_m2=pc.heat_rate.max_W_m2 if pc.heat_rate is not None else None,
        dynamic_pressure_max_Pa=pc.dynamic_pressure.max_Pa if pc.dynamic_pressure else None,
        load_factor_max_g=pc.load_factor.max_g if pc.load_factor else None,
    )


def _lift_range(doc: ProblemDocument) -> tuple[float, float] | None:
    """A parabolic polar's (lambda_min, lambda_max), else None."""
    aero = doc.vehicle.aerodynamics
    if aero.model != "parabolic_polar":
        return None
    return float(aero.lambda_min), float(aero.lambda_max)


def _guess(doc: ProblemDocument, scales: Scales) -> GuessPath | None:
    """The document's initial-guess trajectory, nondimensional, its time from 0."""
    given = doc.initial_guess.trajectory if doc.initial_guess is not None else None
    if given is None:
        return None
    t = np.asarray(given.time_s, dtype=float)
    y = np.column_stack(
        [
            1.0 + np.asarray(given.altitude_m) / scales.radius_m,
            np.radians(given.longitude_deg),
            np.radians(given.latitude_deg),
            np.asarray(given.velocity_m_s) / scales.speed_m_s,
            np.radians(given.flight_path_angle_deg),
            np.radians(given.heading_deg),
        ]
    )
    alpha = np.radians(given.alpha_deg) if given.alpha_deg is not None else None
    return GuessPath(
        t=(t - t[0]) / scales.time_s, y=y, bank=np.radians(given.bank_deg), alpha=alpha
    )


def _optimized_alpha(doc: ProblemDocument, scales: Scales) -> dict[str, Any]:
    """The bounds, rate bound and initial value of an optimized angle of attack (radians,
    radians per nondimensional time); empty for a scheduled one. The rate bound is the
    angle-of-attack law's own, else ``control_limits.alpha_rate_max_deg_s``."""
    spec = doc.vehicle.angle_of_attack
    if spec is None or spec.mode != "optimized":
        return {}
    rate = spec.rate_max_deg_s
    if rate is None:
        rate = doc.control_limits.alpha_rate_max_deg_s
    return {
        "alpha_range": (math.radians(spec.min_deg), math.radians(spec.max_deg)),
        "alpha_rate_max": math.radians(rate) * scales.time_s if rate is not None else None,
        "initial_alpha": math.radians(spec.initial_deg) if spec.initial_deg is not None else None,
    }
