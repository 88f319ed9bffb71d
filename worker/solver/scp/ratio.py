"""SCvx's ratio test (Mao, Szmuk & Acikmese 2016, Algorithm 1; paper 001 sec. 3): a step is
judged by the decrease of the nonlinear merit it achieved against the decrease its convex model
predicted. The ratio decides whether the step is taken and how the trust region changes.

The pieces every method that judges its steps this way shares: ``step_ratio`` (the figures),
``RatioThresholds`` (the verdict) and ``TrustRegion`` (a trust radius, or the weight of a trust
penalty, moved by the verdict within its bounds).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum


class Verdict(StrEnum):
    """What the ratio says of a step: rejected, or taken with the trust region shrunk, kept or
    grown."""

    REJECT = "reject"
    SHRINK = "shrink"
    KEEP = "keep"
    GROW = "grow"


@dataclass(frozen=True)
class StepRatio:
    """A step's predicted and actual decrease of the merit and their ratio."""

    predicted: float
    actual: float
    value: float

    def describe(self) -> dict[str, float]:
        """The figures a history record carries (``extra``)."""
        return {
            "ratio": self.value,
            "predicted_decrease": self.predicted,
            "actual_decrease": self.actual,
        }


def step_ratio(
    reference_merit: float, candidate_merit: float, model_merit: float, stationary: float
) -> StepRatio:
    """The ratio of the actual decrease (``reference_merit - candidate_merit``) to the predicted
    one (``reference_merit - model_merit``, the model's merit of the step). A predicted decrease
    of at most ``stationary`` times the reference's merit (at least 1) gives ratio 1: the model
    sees nothing left to gain, so the step cannot be judged by it and is not rejected for it."""
    predicted = reference_merit - model_merit
    actual = reference_merit - candidate_merit
    scale = max(1.0, abs(reference_merit))
    value = 1.0 if predicted <= stationary * scale else actual / predicted
    return StepRatio(predicted, actual, value)


@dataclass(frozen=True)
class RatioThresholds:
    """A ratio below ``reject`` rejects the step; below ``shrink`` the step is taken and the
    trust region shrunk; above ``grow`` it is taken and the region grown; else kept (with
    ``shrink == reject`` there is no shrinking band)."""

    reject: float
    shrink: float
    grow: float

    def verdict(self, ratio: float) -> Verdict:
        """The verdict on a step of ``ratio``."""
        if ratio < self.reject:
            return Verdict.REJECT
        if ratio < self.shrink:
            return Verdict.SHRINK
        if ratio > self.grow:
            return Verdict.GROW
        return Verdict.KEEP


@dataclass
class TrustRegion:
    """A trust region's ``size`` within [``minimum``, ``maximum``]: a radius (larger allows
    longer steps) or, with ``penalty``, the weight of a trust penalty on the step (larger
    allows shorter ones)."""

    size: float
    minimum: float
    maximum: float
    penalty: bool = False

    def shorten(self, factor: float = 2.0) -> None:
        """Shorter steps: a radius divided, a weight multiplied, by ``factor``."""
        if self.penalty:
            self.size = min(self.size * factor, self.maximum)
        else:
            self.size = max(self.size / factor, self.minimum)

    def lengthen(self, factor: float = 2.0) -> None:
        """Longer steps: a radius multiplied, a weight divided, by ``factor``."""
        if self.penalty:
            self.size = max(self.size / factor, self.minimum)
        else:
            self.size = min(self.size * factor, self.maximum)

    def at_most_as_long_as(self, size: float) -> None:
        """Steps no longer than a region of ``size`` allows (a weight at least ``size``, a
        radius at most ``size``)."""
        self.size = max(self.size, size) if self.penalty else min(self.size, size)

    @property
    def at_longest(self) -> bool:
        """Whether the region allows the longest steps its bounds permit."""
        return self.size <= self.minimum if self.penalty else self.size >= self.maximum


__all__ = ["RatioThresholds", "StepRatio", "TrustRegion", "Verdict", "step_ratio"]
