"""The problem model of a problem in phases, with or without propulsion (paper 004).

A document's ``phases`` become ``PhaseModel`` s (nondimensional bounds per phase); a document
without phases is one phase spanning the whole flight, with the document's terminal conditions,
final time, angle-of-attack and bank bounds and path limits. The vehicle's ``propulsion`` becomes
the ``Thruster`` of the powered dynamics (``models.powered``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from app.schemas import ProblemDocument
from worker.solver.models.powered import G_STANDARD, PoweredModel, Thruster
from worker.solver.path_limits import PathLimits
from worker.solver.problem import (
    EntryProblem,
    TerminalTarget,
    build_problem,
    path_limits_from_spec,
    terminal_targets,
)

DEFAULT_FLIGHT_TIME_MAX_S = 6000.0
"""Longest flight of a single free-time phase whose document gives no ``final_time.max_s``."""
MIN_DURATION_S = 1.0
"""Shortest duration of a single free-time phase whose document gives no bound."""


@dataclass(frozen=True)
class PhaseModel:
    """One phase, nondimensional: duration bounds, end conditions, control bounds (radians, m0
    g0) and path limits."""

    name: str
    duration_min: float
    duration_max: float
    end: dict[str, TerminalTarget]
    end_si: dict[str, TerminalTarget]
    alpha_range: tuple[float, float]
    bank_range: tuple[float, float]
    thrust_max: float
    limits: PathLimits


@dataclass
class PhasedProblem:
    """The phases of a flight, the powered dynamics they share and the initial state."""

    base: EntryProblem
    model: PoweredModel
    phases: list[PhaseModel]
    x0: np.ndarray  # initial state, ``model.n_states`` long
    mass_kg: float  # the initial mass m0, the mass unit

    @property
    def thrust_unit_n(self) -> float:
        """Newtons per nondimensional thrust (m0 g0)."""
        return self.mass_kg * self.base.scales.g0_m_s2


def _thruster(doc: ProblemDocument, base: EntryProblem) -> Thruster | None:
    spec = doc.vehicle.propulsion
    if spec is None:
        return None
    sc = base.scales
    unit = doc.vehicle.mass_kg * sc.g0_m_s2
    lag = spec.thrust_lag_s
    dry = spec.dry_mass_kg
    return Thruster(
        max_thrust=spec.max_thrust_n / unit,
        # dm/dt = -T / (Isp g_std): in m0 per time unit per (m0 g0) of thrust
        flow=sc.g0_m_s2 * sc.time_s / (spec.isp_s * G_STANDARD),
        lag_rate=sc.time_s / lag if lag else None,
        initial_thrust=spec.initial_thrust_n / unit,
        dry_mass=dry / doc.vehicle.mass_kg if dry is not None else None,
    )


def _alpha_range(doc: ProblemDocument, base: EntryProblem) -> tuple[float, float]:
    if base.alpha_range is not None:
        return base.alpha_range
    return (-0.5 * math.pi, 0.5 * math.pi)


def _single_phase(
    doc: ProblemDocument, base: EntryProblem, thruster: Thruster | None
) -> PhaseModel:
    """The whole flight as one phase."""
    ts = base.scales.time_s
    if base.final_time is not None:
        lo = hi = base.final_time
    else:
        lo = MIN_DURATION_S / ts
        hi = (
            base.final_time_max
            if base.final_time_max is not None
            else DEFAULT_FLIGHT_TIME_MAX_S / ts
        )
    return PhaseModel(
        name="flight",
        duration_min=lo,
        duration_max=hi,
        end=base.terminal,
        end_si=base.terminal_si,
        alpha_range=_alpha_range(doc, base),
        bank_range=(base.bank_min, base.bank_max),
        thrust_max=thruster.max_thrust if thruster is not None else 0.0,
        limits=base.limits,
    )


def build_phased_problem(doc: ProblemDocument) -> PhasedProblem:
    """The phased model of a validated document (one phase when it gives none)."""
    base = build_problem(doc)
    sc = base.scales
    thruster = _thruster(doc, base)
    model = PoweredModel(forces=base.forces, omega=base.omega, thruster=thruster)
    phases: list[PhaseModel] = []
    for spec in doc.phases:
        end, end_si = terminal_targets(spec.end, sc)
        alpha = _alpha_range(doc, base)
        if spec.angle_of_attack_deg is not None:
            alpha = (
                math.radians(spec.angle_of_attack_deg.min_deg),
                math.radians(spec.angle_of_attack_deg.max_deg),
            )
        bank_lo = (
            math.radians(spec.bank_min_deg) if spec.bank_min_deg is not None else base.bank_min
        )
        bank_hi = (
            math.radians(spec.bank_max_deg) if spec.bank_max_deg is not None else base.bank_max
        )
        unit = doc.vehicle.mass_kg * sc.g0_m_s2
        if thruster is None:
            thrust_max = 0.0
        elif spec.thrust_max_n is None:
            thrust_max = thruster.max_thrust
        else:
            thrust_max = spec.thrust_max_n / unit
        limits = (
            path_limits_from_spec(spec.path_constraints)
            if spec.path_constraints is not None
            else base.limits
        )
        phases.append(
            PhaseModel(
                name=spec.name,
                duration_min=spec.duration_s.min_s / sc.time_s,
                duration_max=spec.duration_s.max_s / sc.time_s,
                end=end,
                end_si=end_si,
                alpha_range=alpha,
                bank_range=(bank_lo, bank_hi),
                thrust_max=thrust_max,
                limits=limits,
            )
        )
    if not phases:
        phases.append(_single_phase(doc, base, thruster))
    x0 = list(base.y0)
    if thruster is not None:
        x0.append(1.0)
        if thruster.lagged:
            x0.append(thruster.initial_thrust)
    return PhasedProblem(
        base=base, model=model, phases=phases, x0=np.asarray(x0), mass_kg=doc.vehicle.mass_kg
    )
