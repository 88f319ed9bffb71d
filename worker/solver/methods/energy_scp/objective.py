"""The objective of paper 000's method: running costs (heat load, flight time) by the trapezoid
in energy and terminal costs on the last node, each normalized on the initial guess: a running
cost by its value, a terminal cost by its sensitivity per trust-region unit."""

from __future__ import annotations

import math

import numpy as np

from worker.solver.models.point_mass import EnergyDerivatives, EnergyRates
from worker.solver.objective_weights import term_pulls
from worker.solver.objectives import (
    RUNNING_COSTS,
    TERMINAL_COSTS,
    RunningCost,
    energy_running_cost,
    energy_running_density,
    trapezoid,
)
from worker.solver.problem import EntryProblem

Array = np.ndarray
TERMINAL_STEP_UNITS = 25.0
"""Trust units a terminal objective alone would move its last node per iteration (the
subproblem's dynamics and post-correction shorten it): sets the terminal terms' normalization."""


class EnergyObjective:
    """The problem's objective terms, each normalized on the initial reference.

    A running cost is divided by its value there (O(1); its sensitivity to one trust-region
    unit at every node is then ~0.4 for the heat load). A terminal cost is divided by its
    sensitivity, scaled to the trust region: one trust unit (``state_scale``) of its state
    is worth ``2 w_tr (K/3) TERMINAL_STEP_UNITS``, the trust-region curvature of a ramp step
    (zero at the first node, growing linearly to the last, sum of squares ~K/3) that moves the
    last node ``TERMINAL_STEP_UNITS`` units. Divided by its value instead, a terminal latitude
    moves ~1 degree per iteration and stops far from its optimum; this way it moves at the rate
    the trust region allows at any node count. A running cost is evaluated once per
    linearization ``ed`` (the last one is kept).
    """

    def __init__(
        self,
        problem: EntryProblem,
        e: Array,
        x: Array,
        ed: EnergyDerivatives,
        state_scale: Array,
        weight_trust_region: float,
    ) -> None:
        self.problem = problem
        self.e = e
        self.scale: dict[str, float] = {}
        self._cached_ed: EnergyDerivatives | None = None
        self._cached: dict[str, RunningCost] = {}
        gain = 2.0 * weight_trust_region * (e.size / 3.0) * TERMINAL_STEP_UNITS
        for term in problem.objective:
            if term.name in RUNNING_COSTS:
                value = trapezoid(self._running(term.name, x, ed).density, e)
                self.scale[term.name] = abs(value) if value != 0 else 1.0
            else:
                idx, _ = TERMINAL_COSTS[term.name]
                self.scale[term.name] = float(state_scale[idx]) / gain
        terms = list(problem.objective)
        units = [  # each term's SI value (J/m^2, s, deg) per normalized unit
            self.scale[t.name] if t.name in RUNNING_COSTS else math.degrees(self.scale[t.name])
            for t in terms
        ]
        pulls = term_pulls([t.weight for t in terms], units)
        self.pull = {t.name: pull for t, pull in zip(terms, pulls, strict=True)}
        """Each term's weight on its normalized value (``objective_weights.term_pulls``)."""

    def _running(self, name: str, x: Array, ed: EnergyDerivatives) -> RunningCost:
        """Running cost ``name`` on ``x`` (``ed`` is the dynamics at ``x``), cached per ``ed``."""
        if ed is not self._cached_ed:
            self._cached_ed = ed
            self._cached = {}
        cost = self._cached.get(name)
        if cost is None:
            cost = self._cached[name] = energy_running_cost(self.problem, name, x, ed)
        return cost

    def gradients(self, x: Array, ed: EnergyDerivatives) -> tuple[Array, Array]:
        """Running-cost gradient per unit energy (K, 5) and terminal gradient (5,), normalized."""
        run = np.zeros_like(x)
        term = np.zeros(x.shape[1])
        for t in self.problem.objective:
            w = self.pull[t.name] / self.scale[t.name]
            if t.name in RUNNING_COSTS:
                run += w * self._running(t.name, x, ed).gradient
            else:
                idx, sign = TERMINAL_COSTS[t.name]
                term[idx] += w * sign
        return run, term

    def values(self, x: Array, rates: EnergyRates) -> dict[str, float]:
        """Each term's value in SI units (J/m^2, s, deg) on trajectory x (``rates`` at x)."""
        out: dict[str, float] = {}
        for t in self.problem.objective:
            if t.name in RUNNING_COSTS:
                density = energy_running_density(self.problem, t.name, x, rates)
                out[t.name] = trapezoid(density, self.e)
            else:
                idx, _ = TERMINAL_COSTS[t.name]
                out[t.name] = math.degrees(float(x[-1, idx]))
        return out
