"""Paper 003's globalization of the step (sec. 4.3): a hard trust region until the objective
oscillates, then a quadratic penalty 0.5 w_k d'd on the step whose weight follows the history of
the steps (eqs. 61, 77-79).

Oscillation (eq. 61): J_{k-2} > J_{k-3}, J_{k-1} < J_{k-2}, J_k > J_{k-1}. Weight (eq. 77):
w_k = theta_k |grad J| / |d_{k-1}|, so that the linear and the quadratic terms are of one size;
theta_k = theta_{k-1} e_k / e_{k-1} with the efficiency e_k = |d_k| / |d_{k-1}| (eqs. 78-79): steps
shrinking ever faster raise theta (the objective would fall too fast), steps that stop shrinking
lower it. Before the adaptation the weight is 1 (Remark 2); a subproblem that cannot be solved
multiplies it by 10, and a run of iterations without a significant decrease multiplies theta by
Gamma.
"""

from __future__ import annotations

from dataclasses import dataclass, field

WEIGHT_MIN, WEIGHT_MAX = 1.0e-6, 1.0e8
"""Range of the penalty weight (scaled units)."""
GROWTH_MAX = 10.0
"""Largest factor of the weight from one iteration to the next."""


def oscillating(costs: list[float]) -> bool:
    """Paper 003 eq. 61 on the last four objective values (down, up, down, up reversed)."""
    if len(costs) < 4:
        return False
    j3, j2, j1, j0 = costs[-4:]
    return j2 > j3 and j1 < j2 and j0 > j1


@dataclass
class VariableQuadraticPenalty:
    """The stage (hard trust region or penalty) and the penalty weight's state."""

    initial_weight: float = 1.0
    gamma: float = 2.0
    """Gamma of Remark 2: theta's factor after ``stall_iterations`` without a significant
    decrease."""
    stall_iterations: int = 3
    stall_relative: float = 1.0e-4
    rule: str = "line_search"
    """How the weight adapts in the penalty stage: "direction_history" (eqs. 77-79) or
    "line_search" (halved after a whole step that lowered the objective, else doubled)."""
    minimum: float = 1.0e-3
    """Lightest weight of the line-search rule."""
    stage: str = "hard"
    weight: float = 0.0
    theta: float | None = None
    steps: list[float] = field(default_factory=list)
    costs: list[float] = field(default_factory=list)
    _e_prev: float | None = None

    def observe(
        self, cost: float, step_norm: float, gradient_norm: float, full_step: bool = True
    ) -> None:
        """Record an accepted iteration (objective, |d|, |grad J|, whether the line search took
        the whole step) and update the stage and the weight for the next subproblem."""
        self.costs.append(cost)
        self.steps.append(step_norm)
        if self.stage == "hard":
            if oscillating(self.costs):
                self.stage = "penalty"
                self.weight = self.initial_weight
            return
        if self.rule == "line_search":
            # the step's outcome sets the weight: a whole step that lowered the objective
            # halves it (the objective leads), a shortened or rising one doubles it
            down = len(self.costs) > 1 and self.costs[-1] < self.costs[-2]
            factor = 0.5 if full_step and down else 2.0
            self.weight = min(max(self.weight * factor, self.minimum), WEIGHT_MAX)
            return
        if len(self.steps) < 2 or self.steps[-2] <= 0.0:
            return
        e = self.steps[-1] / self.steps[-2]
        if self.theta is None:  # the adaptation starts from the weight in force
            self.theta = self.weight * self.steps[-1] / max(gradient_norm, 1e-300)
        elif self._e_prev is not None and self._e_prev > 0.0 and e > 0.0:
            self.theta *= e / self._e_prev
        self._e_prev = e
        if self._stalled():
            self.theta *= self.gamma
        if step_norm > 0.0 and gradient_norm > 0.0:
            previous = self.weight
            self.weight = self.theta * gradient_norm / step_norm
            # at most a decade per iteration either way: eq. 77 feeds a shrinking step back
            self.weight = min(max(self.weight, previous / GROWTH_MAX), previous * GROWTH_MAX)
        self.weight = min(max(self.weight, WEIGHT_MIN), WEIGHT_MAX)

    def infeasible(self) -> None:
        """A subproblem could not be solved at this weight: ten times heavier (Remark 2)."""
        self.weight = min(max(self.weight, self.initial_weight) * 10.0, WEIGHT_MAX)

    def _stalled(self) -> bool:
        n = self.stall_iterations
        if len(self.costs) <= n:
            return False
        old, new = self.costs[-n - 1], self.costs[-1]
        return old - new < self.stall_relative * max(abs(old), 1.0)

    @property
    def hard(self) -> bool:
        """Whether the hard trust region is in force (stage 1)."""
        return self.stage == "hard"

    def describe(self) -> dict[str, float | str | None]:
        """The state a history record carries."""
        return {
            "stage": self.stage,
            "penalty_weight": self.weight,
            "theta": self.theta,
        }


__all__ = ["VariableQuadraticPenalty", "oscillating"]
