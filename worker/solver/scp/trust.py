"""Globalization strategies: how the weight of a penalized trust region follows the iterates.

Paper 000 keeps its trust-region weight fixed; the energy method holds it for the first
iterations and then relaxes it (``RelaxingTrustWeight``; a factor of 1 keeps the paper's); the
time-domain method adapts it to the defect of each step (``DefectTrustWeight``: paper 002 keeps
it fixed, which stalls or wanders on other problems). Beside them: the SCvx ratio test
(``scp.ratio``), paper 003's filter (``scp.filter``) and quadratic penalty (``scp.penalty``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

Array = np.ndarray

TRUST_WEIGHT_MAX = 1e3
"""Heaviest trust weight: beyond it a step is too short to move the iterates at all."""


def step_cosine(step: Array, last: Array | None) -> float:
    """Cosine between ``step`` and the previous step ``last`` (0 without one, or for a zero
    step): below a negative threshold the iterates swing back."""
    if last is None:
        return 0.0
    norm = float(np.linalg.norm(step) * np.linalg.norm(last))
    return float(np.dot(step, last)) / norm if norm > 0.0 else 0.0


@dataclass
class RelaxingTrustWeight:
    """The paper's weight for the first ``hold`` iterations, then ``factor`` times lighter per
    iteration down to ``minimum``, and ``1 / factor**2`` times heavier (up to the initial
    weight) after a step that swings back against the previous one (cosine below
    ``-reversal_cosine``): a fixed weight heavy enough to globalize the first steps also damps
    every later one, so the iterates creep towards the optimum and a step-size stop test fires
    early (measured on paper 000's case and its variants, docs/methods); with no weight at all
    the states the objective does not pin swing from one side to the other. ``relaxed`` says
    the weight has reached its floor once: only then is a small step a stationary one."""

    initial: float
    minimum: float
    factor: float
    hold: int
    reversal_cosine: float = 0.5

    def __post_init__(self) -> None:
        self.weight = self.initial
        # a factor of 1 keeps the weight: its floor is then the weight itself
        self.floor = self.initial if self.factor >= 1.0 else min(self.minimum, self.initial)
        self.relaxed = self.weight <= self.floor
        self._last_step: Array | None = None

    def after_iteration(self, iteration: int, step: Array) -> None:
        """Relax (or, after a swing back, stiffen) the weight once ``iteration`` is past the
        held ones; ``step`` is the iteration's state step in trust units."""
        last, self._last_step = self._last_step, step
        if iteration < self.hold:
            return
        if step_cosine(step, last) < -self.reversal_cosine:
            self.weight = min(self.weight / self.factor**2, self.initial)
        else:
            self.weight = max(self.weight * self.factor, self.floor)
        self.relaxed = self.relaxed or self.weight <= self.floor * (1.0 + 1e-9)

    def rejected(self) -> bool:
        """After a step whose linear model broke down: the weight that made it was too light
        for this problem, so the next try is ``1 / factor**2`` times heavier (two relaxations
        undone) and the floor is raised to one relaxation above it for the rest of the run.
        False (nothing changed) for a fixed weight (a factor of 1, the paper's): the step is
        then taken."""
        if self.factor >= 1.0:
            return False
        self.floor = max(self.floor, self.weight / self.factor)
        self.weight = max(self.weight / self.factor**2, self.floor)
        self.relaxed = False
        self._last_step = None
        return True


@dataclass
class DefectTrustWeight:
    """Adapt the trust weight w_tr to each step's defect, and grow it when the steps swing back.

    A step's defect (nodes minus their own propagation) grows about as the square of its
    length, and its length as 1 / w_tr, so w_tr is scaled by sqrt(defect / target) within
    ``factor`` either way; a step that points back against the previous one (cosine below
    ``-reversal_cosine``) or that is rejected multiplies it by ``factor``.
    """

    initial: float
    minimum: float
    defect_target: float
    factor: float
    reversal_cosine: float

    def __post_init__(self) -> None:
        self.weight = self.initial
        self._last_step: Array | None = None

    def reversal(self, step: Array) -> float:
        """Cosine between ``step`` and the last accepted step (0 for the first)."""
        return step_cosine(step, self._last_step)

    def accepted(self, step: Array, reversal: float, defect: float) -> None:
        """Update after an accepted step with its reversal cosine and defect (scaled units)."""
        if reversal < -self.reversal_cosine:  # the iterates swing back
            self.weight = min(self.weight * self.factor, TRUST_WEIGHT_MAX)
        else:
            ratio = math.sqrt(max(defect, 1e-12) / self.defect_target)
            ratio = min(max(ratio, 1.0 / self.factor), self.factor)
            self.weight = min(max(self.weight * ratio, self.minimum), TRUST_WEIGHT_MAX)
        self._last_step = step

    def rejected(self) -> None:
        """Update after a rejected step: a shorter next step."""
        self.weight = min(self.weight * self.factor, TRUST_WEIGHT_MAX)
