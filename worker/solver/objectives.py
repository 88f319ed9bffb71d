"""Objective terms in the energy domain: running costs per unit energy and terminal costs.

Heat load J = int Qdot dt = int Qdot / (de/dt) de (paper 000 eq. 18-19, with the exact de/dt);
flight time t_f = int 1 / (de/dt) de. Each returns its value density and gradient in the
energy-form state x = [r, theta, phi, gamma, psi], dimensional (J/m^2 or s per unit energy).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worker.solver.models.point_mass import EnergyDerivatives, EnergyRates
from worker.solver.path_limits import PathValues, path_values
from worker.solver.problem import EntryProblem

Array = np.ndarray

RUNNING_COSTS = ("min_heat_load", "min_time")
TERMINAL_COSTS = {  # name -> (energy-form state index, sign of the minimized quantity)
    "max_final_latitude": (2, -1.0),
    "min_final_latitude": (2, 1.0),
    "max_final_longitude": (1, -1.0),
    "min_final_longitude": (1, 1.0),
}


UNITS = {
    "min_heat_load": "J/m^2",
    "min_time": "s",
    "max_final_latitude": "deg",
    "min_final_latitude": "deg",
    "max_final_longitude": "deg",
    "min_final_longitude": "deg",
    "max_terminal_velocity": "m/s",
    "min_control_effort": "deg",
    "min_propellant": "kg",
}


@dataclass
class RunningCost:
    """Density g(x) per unit energy and its gradient (K,) and (K, 5)."""

    density: Array
    gradient: Array


def _heat_rate(problem: EntryProblem, x: Array, ed: EnergyDerivatives | EnergyRates) -> PathValues:
    """Heat rate and its partials along the nodes, from the force terms already in ``ed``."""
    if problem.heat_model is None:
        raise ValueError("min_heat_load needs path_constraints.heat_rate (the heating model)")
    return path_values(problem.forces, problem.heat_model, x[:, 0], ed.speed, ed.time.forces)


def energy_running_density(
    problem: EntryProblem, name: str, x: Array, ed: EnergyDerivatives | EnergyRates
) -> Array:
    """Heat-load or time density along energy nodes (no gradient): ``energy_running_cost``'s value.

    ``ed`` must be ``energy_rates`` or ``energy_dynamics`` at ``x`` (its force terms are reused).
    """
    t_scale = problem.scales.time_s
    inv = 1.0 / ed.edot
    if name == "min_time":
        density: Array = t_scale * inv
        return density
    if name != "min_heat_load":
        raise ValueError(f"{name} is not a running cost")
    density = t_scale * _heat_rate(problem, x, ed).heat_rate * inv
    return density


def energy_running_cost(
    problem: EntryProblem, name: str, x: Array, ed: EnergyDerivatives
) -> RunningCost:
    """Heat-load or time density along energy nodes, with its gradient in x.

    ``ed`` must be ``energy_dynamics`` at ``x``: its force terms are reused, not recomputed.
    """
    t_scale = problem.scales.time_s
    inv = 1.0 / ed.edot
    if name == "min_time":
        density = t_scale * inv
        gradient = -t_scale * ed.edot_x * (inv * inv)[:, None]
        return RunningCost(density, gradient)
    if name != "min_heat_load":
        raise ValueError(f"{name} is not a running cost")
    pv = _heat_rate(problem, x, ed)
    r = x[:, 0]
    v = ed.speed
    v_r = -1.0 / (r * r * v)
    qdot_x = np.zeros_like(x)
    qdot_x[:, 0] = pv.heat_rate_r + pv.heat_rate_v * v_r
    density = t_scale * pv.heat_rate * inv
    gradient = t_scale * (
        qdot_x * inv[:, None] - pv.heat_rate[:, None] * ed.edot_x * (inv * inv)[:, None]
    )
    return RunningCost(density, gradient)


def trapezoid(values: Array, e: Array) -> float:
    """Trapezoidal integral over the energy grid."""
    return float(np.sum(0.5 * (values[1:] + values[:-1]) * np.diff(e)))
