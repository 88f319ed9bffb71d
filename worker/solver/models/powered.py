"""Point-mass entry dynamics with thrust and mass: paper 004's skip entry with a rocket.

State x = [r, theta, phi, V, gamma, psi] (nondimensional, ``units.Scales``), followed, when the
vehicle has propulsion, by the mass m (relative to the initial mass m0) and, when the thrust
lags its command, by the thrust T (in m0 g0). Controls u = [alpha (rad), sigma (rad)] and, with
propulsion, the commanded thrust Tc (in m0 g0).

Paper 004's eq. (1) is garbled (../NOTES: its kinematics swap cos/sin of the heading and divide
L, D by m twice); the standard point-mass form is used, the one the shared NLP reference flies:
the thrust acts along the body axis at alpha, so it adds T cos(alpha) to the tangential force and
T sin(alpha) to the lift, both banked by sigma (Vinh, Busemann & Culp 1980, ch. 2). The six
point-mass rates are ``models.eom`` with lift and drag replaced by (L + T sin a)/m and
(D - T cos a)/m: one source of the equations for every method. Mass flow m' = -T / (Isp g_std)
with standard gravity 9.80665 m/s^2; thrust lag T' = (Tc - T) / tau (paper 004's
K_T pi (Tc - T) / T_max with tau = T_max / (pi K_T)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worker.solver.forces import VehicleForces
from worker.solver.models import eom
from worker.solver.path_limits import PathLimits, path_values

Array = np.ndarray

G_STANDARD = 9.80665
"""Standard gravity, m/s^2: the one specific impulse is defined with."""


@dataclass(frozen=True)
class Thruster:
    """Propulsion in nondimensional units: the largest thrust (m0 g0), the mass flow per unit
    thrust (dm/dt = -flow T) and the lag rate 1/tau (None: the thrust is the command)."""

    max_thrust: float
    flow: float
    lag_rate: float | None
    initial_thrust: float = 0.0
    dry_mass: float | None = None  # relative to m0

    @property
    def lagged(self) -> bool:
        return self.lag_rate is not None


@dataclass(frozen=True)
class PoweredModel:
    """What the powered dynamics need: forces (aerodynamics of the initial mass), rotation,
    and the thruster (None: an unpowered vehicle of constant mass)."""

    forces: VehicleForces
    omega: float
    thruster: Thruster | None

    @property
    def n_states(self) -> int:
        if self.thruster is None:
            return 6
        return 8 if self.thruster.lagged else 7

    @property
    def n_controls(self) -> int:
        return 2 if self.thruster is None else 3

    def mass(self, x: Array) -> Array:
        """Mass relative to m0 at every row of ``x``."""
        return x[:, 6] if self.thruster is not None else np.ones(x.shape[0])

    def thrust(self, x: Array, u: Array) -> Array:
        """Thrust acting (m0 g0): the lagged state, else the command, else zero."""
        if self.thruster is None:
            return np.zeros(x.shape[0])
        return x[:, 7] if self.thruster.lagged else u[:, 2]

    def rates(self, x: Array, u: Array) -> Array:
        """dx/dt at every row of ``x`` (N, n_states) under ``u`` (N, n_controls)."""
        r, ph, v, ga, ps = x[:, 0], x[:, 2], x[:, 3], x[:, 4], x[:, 5]
        alpha, sigma = u[:, 0], u[:, 1]
        ft = self.forces.terms(r, v, np.degrees(alpha))
        m = self.mass(x)
        thrust = self.thrust(x, u)
        lift = (ft.lift + thrust * np.sin(alpha)) / m
        drag = (ft.drag - thrust * np.cos(alpha)) / m
        k = eom.kinematics(r, ph, v, ga, ps, False)
        rt = eom.rates(k, r, v, lift, drag, np.cos(sigma), np.sin(sigma), self.omega, False, False)
        out = np.empty((x.shape[0], self.n_states), dtype=np.result_type(x, u, ft.lift))
        for i, rate in enumerate(rt):
            out[:, i] = rate
        if self.thruster is not None:
            out[:, 6] = -self.thruster.flow * thrust
            if self.thruster.lag_rate is not None:
                out[:, 7] = self.thruster.lag_rate * (u[:, 2] - x[:, 7])
        return out


@dataclass
class PoweredPathValues:
    """Path quantities at the rows of a state: heat rate (W/m^2), dynamic pressure (Pa) and
    the aerodynamic load factor sqrt(L^2 + D^2) / (m g0) (thrust not included, as paper 004)."""

    heat_rate: Array
    dynamic_pressure: Array
    load_factor: Array


def powered_path_values(
    model: PoweredModel, limits: PathLimits, x: Array, u: Array
) -> PoweredPathValues:
    """Heat rate, dynamic pressure and load factor at every row of ``x`` under ``u``."""
    r, v = x[:, 0], x[:, 3]
    ft = model.forces.terms(r, v, np.degrees(u[:, 0]))
    pv = path_values(model.forces, limits.heat, r, v, ft)
    return PoweredPathValues(pv.heat_rate, pv.dynamic_pressure, pv.load_factor / model.mass(x))


def path_ratios(model: PoweredModel, limits: PathLimits, x: Array, u: Array) -> Array:
    """(N, k) value / limit of each active path limit (heat, dynamic pressure, load factor, in
    that order, absent limits left out): <= 1 where the limits hold."""
    pv = powered_path_values(model, limits, x, u)
    cols = []
    if limits.heat_max_W_m2 is not None and limits.heat is not None:
        cols.append(pv.heat_rate / limits.heat_max_W_m2)
    if limits.dynamic_pressure_max_Pa is not None:
        cols.append(pv.dynamic_pressure / limits.dynamic_pressure_max_Pa)
    if limits.load_factor_max_g is not None:
        cols.append(pv.load_factor / limits.load_factor_max_g)
    if not cols:
        return np.zeros((x.shape[0], 0))
    return np.stack(cols, axis=1)
