"""Objective terms of the time-domain SCP: terminal states and the heat load, linearized.

Terminal terms (paper 002 Problem 1: J = -V(t_f); also extreme final latitude or longitude) enter
through the last node; the heat load is the trapezoid over the nodes with the interval lengths s_k,
so it depends on s as well as on (r, V); the flight time (a free final time) is the sum of the
interval lengths. Each term is normalized so a unit change of the scaled variable (terminal
terms) or 1 % of the initial reference's heat load or flight time costs 1.
"""

from __future__ import annotations

import math

import numpy as np

from worker.solver.forces import ForceTerms
from worker.solver.objective_weights import term_pulls
from worker.solver.path_limits import path_values
from worker.solver.problem import EntryProblem

Array = np.ndarray

TERMINAL_TERMS: dict[str, tuple[int, float]] = {  # name -> (state index, sign of the minimized)
    "max_terminal_velocity": (3, -1.0),
    "max_final_latitude": (2, -1.0),
    "min_final_latitude": (2, 1.0),
    "max_final_longitude": (1, -1.0),
    "min_final_longitude": (1, 1.0),
}
RUNNING_TERMS = ("min_heat_load", "min_time")
OBJECTIVES = (*TERMINAL_TERMS, *RUNNING_TERMS)


def node_weights(s: Array) -> Array:
    """Trapezoid weights of the nodes for interval lengths ``s`` (N,): (s_{k-1} + s_k) / 2."""
    w = np.zeros(s.size + 1)
    w[:-1] += 0.5 * s
    w[1:] += 0.5 * s
    return w


class TimeObjective:
    """The problem's objective on time nodes: normalized gradients and SI values."""

    def __init__(self, problem: EntryProblem, state_scale: Array, z: Array, s: Array) -> None:
        self.problem = problem
        self.scale = np.asarray(state_scale, dtype=float)
        self.heat_unit = 1.0
        self.time_unit = 0.01 * float(np.sum(s)) * problem.scales.time_s
        for term in problem.objective:
            if term.name not in OBJECTIVES:
                raise ValueError(f"objective {term.name!r} is not supported in the time domain")
            if term.name == "min_heat_load":
                ft = problem.forces.terms(z[:, 0], z[:, 3])
                load = self._heat_load(z, s, ft)
                self.heat_unit = 0.01 * load if load > 0 else 1.0
        terms = list(problem.objective)
        pulls = term_pulls([t.weight for t in terms], [self._unit(t.name) for t in terms])
        self.pull = {t.name: pull for t, pull in zip(terms, pulls, strict=True)}
        """Each term's weight on its normalized value (``objective_weights.term_pulls``)."""

    def _unit(self, name: str) -> float:
        """A term's SI value (m/s, deg, J/m^2) per unit of its normalized value."""
        if name in TERMINAL_TERMS:
            idx, _ = TERMINAL_TERMS[name]
            scale = float(self.scale[idx])
            return scale * self.problem.scales.speed_m_s if idx == 3 else math.degrees(scale)
        return self.time_unit if name == "min_time" else self.heat_unit

    def _heat(self, z: Array, ft: ForceTerms) -> tuple[Array, Array, Array]:
        if self.problem.heat_model is None:
            raise ValueError("min_heat_load needs path_constraints.heat_rate (the heating model)")
        pv = path_values(self.problem.forces, self.problem.heat_model, z[:, 0], z[:, 3], ft)
        return pv.heat_rate, pv.heat_rate_r, pv.heat_rate_v

    def _heat_load(self, z: Array, s: Array, ft: ForceTerms) -> float:
        q, _, _ = self._heat(z, ft)
        return float(np.dot(node_weights(s), q) * self.problem.scales.time_s)

    def gradients(self, z: Array, s: Array, ft: ForceTerms | None = None) -> tuple[Array, Array]:
        """d J / d z (K, 7) and d J / d s (N,) of the normalized objective at the reference
        (``ft``: the force terms at the nodes, evaluated here when a term needs them)."""
        grad_z = np.zeros(z.shape)
        grad_s = np.zeros(s.size)
        for term in self.problem.objective:
            if term.name in TERMINAL_TERMS:
                idx, sign = TERMINAL_TERMS[term.name]
                grad_z[-1, idx] += self.pull[term.name] * sign / self.scale[idx]
            elif term.name == "min_time":
                grad_s += self.pull[term.name] * self.problem.scales.time_s / self.time_unit
            else:
                if ft is None:
                    ft = self.problem.forces.terms(z[:, 0], z[:, 3])
                q, q_r, q_v = self._heat(z, ft)
                c = self.pull[term.name] * self.problem.scales.time_s / self.heat_unit
                wk = node_weights(s)
                grad_z[:, 0] += c * wk * q_r
                grad_z[:, 3] += c * wk * q_v
                grad_s += c * 0.5 * (q[:-1] + q[1:])
        return grad_z, grad_s

    def values(self, z: Array, s: Array, ft: ForceTerms | None = None) -> dict[str, float]:
        """Each term's value in SI units (m/s, deg, J/m^2) on nodes ``z`` with lengths ``s``."""
        out: dict[str, float] = {}
        for term in self.problem.objective:
            if term.name == "max_terminal_velocity":
                out[term.name] = float(z[-1, 3] * self.problem.scales.speed_m_s)
            elif term.name in TERMINAL_TERMS:
                out[term.name] = math.degrees(float(z[-1, TERMINAL_TERMS[term.name][0]]))
            elif term.name == "min_time":
                out[term.name] = float(np.sum(s)) * self.problem.scales.time_s
            else:
                forces = ft if ft is not None else self.problem.forces.terms(z[:, 0], z[:, 3])
                out[term.name] = self._heat_load(z, s, forces)
        return out

    def normalized(self, values: dict[str, float]) -> float:
        """The weighted, normalized objective from SI ``values`` (comparable across iterations)."""
        total = 0.0
        sc = self.problem.scales
        for term in self.problem.objective:
            v = values[term.name]
            if term.name in TERMINAL_TERMS:
                idx, sign = TERMINAL_TERMS[term.name]
                nd = v / sc.speed_m_s if idx == 3 else math.radians(v)
                total += self.pull[term.name] * sign * nd / self.scale[idx]
            else:
                total += self.pull[term.name] * v / self._unit(term.name)
        return total
