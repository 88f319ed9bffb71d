"""State layouts: which states a model carries, in which order, and how each converts to SI.

A method never indexes states by a module constant: it asks its model's ``StateLayout`` for the
size, the index of a state, the unit of a scaled deviation (the trust region's), the stop
tolerances read from its options, the per-state report of a step and the states that have a
terminal condition. One layout per model: the 7-state bank-state model of paper 002, the 5-state
energy form of paper 000 and the 8-state model with angle of attack and bank as states.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from worker.solver.trajectory import TIME_STATE_NAMES
from worker.solver.units import Scales

Array = np.ndarray
Quantity = Literal["radius", "angle", "speed", "ratio"]
"""How a state converts: radius (nondimensional 1 + h/R0, reported as altitude in metres),
angle (radians, reported in degrees), speed (V / sqrt(R0 g0), reported in m/s) or ratio (a
number without unit, reported as it is: a polar's normalized lift)."""


@dataclass(frozen=True)
class StateComponent:
    """One state: its SI name, its quantity and the unit of its scaled deviation.

    ``trust_unit`` is in the reported unit (m, deg, m/s) unless ``trust_unit_nondimensional``,
    when it is already in the model's nondimensional unit.
    """

    name: str
    quantity: Quantity
    trust_unit: float
    trust_unit_nondimensional: bool = False


def _delta_to_nd(quantity: Quantity, value: float, scales: Scales) -> float:
    """A change of a state in its SI unit (m, deg, m/s) as a nondimensional change."""
    if quantity == "radius":
        return value / scales.radius_m
    if quantity == "speed":
        return value / scales.speed_m_s
    if quantity == "ratio":
        return value
    return math.radians(value)


def _delta_to_si(quantity: Quantity, value: float, scales: Scales) -> float:
    """A nondimensional change of a state in its SI unit (m, deg, m/s)."""
    if quantity == "radius":
        return float(value * scales.radius_m)
    if quantity == "speed":
        return float(value * scales.speed_m_s)
    if quantity == "ratio":
        return float(value)
    return math.degrees(value)


@dataclass(frozen=True)
class StateLayout:
    """The ordered states of a model and their conversions (see the module docstring)."""

    name: str
    components: tuple[StateComponent, ...]

    @property
    def size(self) -> int:
        """Number of states."""
        return len(self.components)

    @property
    def names(self) -> tuple[str, ...]:
        """The states' SI names, in order."""
        return tuple(c.name for c in self.components)

    def index(self, name: str) -> int:
        """Position of the state called ``name`` (ValueError when the model has none)."""
        for j, c in enumerate(self.components):
            if c.name == name:
                return j
        raise ValueError(f"the {self.name} layout has no state {name!r}")

    def has(self, name: str) -> bool:
        """Whether the model carries the state called ``name``."""
        return any(c.name == name for c in self.components)

    def trust_units(self, scales: Scales) -> Array:
        """Unit of each scaled state deviation (nondimensional): the trust region's metric."""
        return np.array(
            [
                c.trust_unit
                if c.trust_unit_nondimensional
                else _delta_to_nd(c.quantity, c.trust_unit, scales)
                for c in self.components
            ]
        )

    def deltas_from_si(self, values: Mapping[str, float] | Any, scales: Scales) -> Array:
        """Per-state changes given in SI by state name (a mapping, or an object with one
        attribute per name such as a stop-tolerance model), as nondimensional changes."""
        get = values.__getitem__ if isinstance(values, Mapping) else values.__getattribute__
        return np.array(
            [_delta_to_nd(c.quantity, float(get(c.name)), scales) for c in self.components]
        )

    def deltas_to_si(self, m: Array, scales: Scales) -> dict[str, float]:
        """Per-state nondimensional changes ``m`` reported in SI units, by state name."""
        return {
            c.name: _delta_to_si(c.quantity, m[j], scales) for j, c in enumerate(self.components)
        }

    def terminal_states(self) -> tuple[tuple[int, str], ...]:
        """(index, name) of every state that can carry a terminal condition, in order."""
        return tuple(
            (j, c.name) for j, c in enumerate(self.components) if c.name in TIME_STATE_NAMES
        )


_ALTITUDE = StateComponent("altitude_m", "radius", 1e3)
_SPEED = StateComponent("velocity_m_s", "speed", 50.0)

BANK_STATE = StateLayout(
    "bank-state",
    (
        _ALTITUDE,
        StateComponent("longitude_deg", "angle", 0.5),
        StateComponent("latitude_deg", "angle", 0.5),
        _SPEED,
        StateComponent("flight_path_angle_deg", "angle", 0.5),
        StateComponent("heading_deg", "angle", 1.0),
        StateComponent("bank_deg", "angle", 5.0),
    ),
)
"""Paper 002's time-domain model: [r, theta, phi, V, gamma, psi, sigma], bank rate as control.
Trust units are roughly one late-iteration step of each state (1 km, 0.5 deg, 0.5 deg, 50 m/s,
0.5 deg, 1 deg, 5 deg), so the trust region treats them alike."""

ALPHA_BANK_STATE = StateLayout(
    "alpha-bank-state",
    (*BANK_STATE.components, StateComponent("angle_of_attack_deg", "angle", 1.0)),
)
"""Time-domain model with angle of attack and bank as states and their rates as controls:
[r, theta, phi, V, gamma, psi, sigma, alpha] (the Shuttle problems, paper 003)."""

LIFT_BANK_STATE = StateLayout(
    "lift-bank-state",
    (*BANK_STATE.components, StateComponent("normalized_lift", "ratio", 0.05)),
)
"""Time-domain model of a parabolic polar with the normalized lift lambda (CL / CL*, paper 001)
and bank as states and their rates as controls: [r, theta, phi, V, gamma, psi, sigma, lambda].
Trust unit 0.05 in lambda (a twentieth of its usual range)."""

ENERGY = StateLayout(
    "energy",
    (
        StateComponent("altitude_m", "radius", 1.0e-3, trust_unit_nondimensional=True),
        StateComponent("longitude_deg", "angle", 1.0),
        StateComponent("latitude_deg", "angle", 1.0),
        StateComponent("flight_path_angle_deg", "angle", 0.5),
        StateComponent("heading_deg", "angle", 1.0),
    ),
)
"""Paper 000's energy-form state [r, theta, phi, gamma, psi] (energy is the independent
variable). Trust units: 1e-3 in radius (6.4 km on Earth), 1 deg in the angles, 0.5 deg in the
flight-path angle, which moves least."""

POINT_MASS = StateLayout("point-mass", BANK_STATE.components[:6])
"""The point-mass time-domain state [r, theta, phi, V, gamma, psi] alone, with the lift vector as
the control (paper 001): the trust units of ``BANK_STATE``'s point-mass states."""
