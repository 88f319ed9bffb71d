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
from worker.solver.transcription.foh_exact import IntervalSamples

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


def quadrature_weights(samples: int) -> Array:
    """Weights of an integral over tau in [0, 1] from ``samples`` equally spaced values, ends
    included: Simpson's rule for an even number of steps, else the trapezoid."""
    steps = samples - 1
    h = 1.0 / steps
    if steps % 2 == 0:
        w = np.full(samples, 2.0)
        w[1::2] = 4.0
        w[0] = w[-1] = 1.0
        return w * (h / 3.0)
    w = np.full(samples, h)
    w[0] = w[-1] = 0.5 * h
    return w


def node_weights(s: Array) -> Array:
    """Trapezoid weights of the nodes for interval lengths ``s`` (N,): (s_{k-1} + s_k) / 2."""
    w = np.zeros(s.size + 1)
    w[:-1] += 0.5 * s
    w[1:] += 0.5 * s
    return w


class TimeObjective:
    """The problem's objective on time nodes: normalized gradients and SI values."""

    def __init__(
        self,
        problem: EntryProblem,
        state_scale: Array,
        z: Array,
        s: Array,
        alpha: int | None = None,
        unit: float = 180.0 / math.pi,
    ) -> None:
        self.problem = problem
        self.scale = np.asarray(state_scale, dtype=float)
        self.alpha = alpha
        """Index of an angle-of-attack state the heating depends on, else None."""
        self.unit = unit
        """The aerodynamic argument (degrees, or a polar's lambda) per unit of that state."""
        self.heat_unit = 1.0
        self.time_unit = 0.01 * float(np.sum(s)) * problem.scales.time_s
        for term in problem.objective:
            if term.name not in OBJECTIVES:
                raise ValueError(f"objective {term.name!r} is not supported in the time domain")
            if term.name == "min_heat_load":
                ft = self._terms(z)
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

    def _terms(self, z: Array) -> ForceTerms:
        """The force terms at the nodes, at their angle of attack when it is a state."""
        alpha = None if self.alpha is None else z[:, self.alpha] * self.unit
        return self.problem.forces.terms(z[:, 0], z[:, 3], alpha)

    def _heat(self, z: Array, ft: ForceTerms) -> tuple[Array, Array, Array, Array | None]:
        if self.problem.heat_model is None:
            raise ValueError("min_heat_load needs path_constraints.heat_rate (the heating model)")
        pv = path_values(self.problem.forces, self.problem.heat_model, z[:, 0], z[:, 3], ft)
        return pv.heat_rate, pv.heat_rate_r, pv.heat_rate_v, pv.heat_rate_a

    def _heat_load(self, z: Array, s: Array, ft: ForceTerms) -> float:
        q = self._heat(z, ft)[0]
        return float(np.dot(node_weights(s), q) * self.problem.scales.time_s)

    def sampled_heat(self, samples: IntervalSamples, s: Array) -> tuple[float, Array]:
        """The heat load over every interval's samples (Simpson's rule in tau over the FOH
        substeps, trapezoid for an odd count) and its gradient in each interval's variables
        [z_k | w_k | w_{k+1} | s_k] (N, nz + 2 m + 1), normalized like ``gradients``.

        With an angle-of-attack state, the heating factor qa(alpha) varies between the nodes
        as alpha does: the nodes' trapezoid would let the grid skip the heating between them.
        """
        n, j, nz = samples.x.shape
        x = samples.x.reshape(n * j, nz)
        pv = path_values(
            self.problem.forces, self.problem.heat_model, x[:, 0], x[:, 3], self._terms(x)
        )
        shape = (n, j)
        q = pv.heat_rate.reshape(shape)
        weights = quadrature_weights(j)
        per_tau = q @ weights  # (N,) integral of q over tau in [0, 1]
        load = float(np.dot(s, per_tau) * self.problem.scales.time_s)
        grad_x = np.zeros((n, j, nz))
        grad_x[..., 0] = pv.heat_rate_r.reshape(shape)
        grad_x[..., 3] = pv.heat_rate_v.reshape(shape)
        if self.alpha is not None and pv.heat_rate_a is not None:
            grad_x[..., self.alpha] = pv.heat_rate_a.reshape(shape) * self.unit
        grad_x *= (weights * s[:, None])[:, :, None]
        block = np.einsum("nji,njic->nc", grad_x, samples.jacobian)
        block[:, -1] += per_tau
        return load, block

    def gradients(
        self,
        z: Array,
        s: Array,
        ft: ForceTerms | None = None,
        heat_block: Array | None = None,
        w_shape: tuple[int, ...] | None = None,
    ) -> tuple[Array, Array, Array | None]:
        """d J / d z (K, nz), d J / d s (N,) and d J / d w (``w_shape``, or None when J does
        not depend on w) of the normalized objective at the reference (``ft``: the force terms
        at the nodes, evaluated here when a term needs them; ``heat_block``: the gradient of
        the heat load over the substeps, ``sampled_heat``'s, which then replaces the nodes')."""
        grad_z = np.zeros(z.shape)
        grad_s = np.zeros(s.size)
        grad_w = None
        for term in self.problem.objective:
            if term.name in TERMINAL_TERMS:
                idx, sign = TERMINAL_TERMS[term.name]
                grad_z[-1, idx] += self.pull[term.name] * sign / self.scale[idx]
            elif term.name == "min_time":
                grad_s += self.pull[term.name] * self.problem.scales.time_s / self.time_unit
            elif heat_block is not None:
                c = self.pull[term.name] * self.problem.scales.time_s / self.heat_unit
                block = heat_block * c  # d(load / time unit): per unit of the normalized load
                nz = z.shape[1]
                m = (block.shape[1] - nz - 1) // 2
                grad_z[:-1] += block[:, :nz]
                gw = np.zeros((z.shape[0], m))
                gw[:-1] += block[:, nz : nz + m]
                gw[1:] += block[:, nz + m : nz + 2 * m]
                grad_w = gw.reshape(w_shape) if w_shape is not None else gw
                grad_s += block[:, -1]
            else:
                if ft is None:
                    ft = self._terms(z)
                q, q_r, q_v, q_a = self._heat(z, ft)
                c = self.pull[term.name] * self.problem.scales.time_s / self.heat_unit
                wk = node_weights(s)
                grad_z[:, 0] += c * wk * q_r
                grad_z[:, 3] += c * wk * q_v
                if self.alpha is not None and q_a is not None:  # per unit of the state
                    grad_z[:, self.alpha] += c * wk * q_a * self.unit
                grad_s += c * 0.5 * (q[:-1] + q[1:])
        return grad_z, grad_s, grad_w

    def values(
        self,
        z: Array,
        s: Array,
        ft: ForceTerms | None = None,
        heat_load: float | None = None,
    ) -> dict[str, float]:
        """Each term's value in SI units (m/s, deg, J/m^2) on nodes ``z`` with lengths ``s``
        (``heat_load``: the load over the substeps, ``sampled_heat``'s, when it was taken)."""
        out: dict[str, float] = {}
        for term in self.problem.objective:
            if term.name == "max_terminal_velocity":
                out[term.name] = float(z[-1, 3] * self.problem.scales.speed_m_s)
            elif term.name in TERMINAL_TERMS:
                out[term.name] = math.degrees(float(z[-1, TERMINAL_TERMS[term.name][0]]))
            elif term.name == "min_time":
                out[term.name] = float(np.sum(s)) * self.problem.scales.time_s
            elif heat_load is not None:
                out[term.name] = heat_load
            else:
                forces = ft if ft is not None else self._terms(z)
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
