"""The shared ratio test (``worker.solver.scp.ratio``): figures, verdicts and trust-region moves.

Pure logic on exact binary fractions, so equalities are exact (tolerance none)."""

from __future__ import annotations

import pytest

from worker.solver.scp.ratio import RatioThresholds, TrustRegion, Verdict, step_ratio

SCVX = RatioThresholds(reject=0.0, shrink=0.25, grow=0.7)


def test_ratio_is_actual_over_predicted_decrease() -> None:
    ratio = step_ratio(10.0, 9.0, 8.0, 1e-9)  # predicted 2, achieved 1
    assert (ratio.predicted, ratio.actual, ratio.value) == (2.0, 1.0, 0.5)
    assert ratio.describe() == {"ratio": 0.5, "predicted_decrease": 2.0, "actual_decrease": 1.0}


def test_a_step_that_raises_the_merit_has_a_negative_ratio() -> None:
    assert step_ratio(10.0, 11.0, 8.0, 1e-9).value == -0.5


@pytest.mark.parametrize("model", [10.0, 10.5, 10.0 - 5e-10])
def test_no_predicted_decrease_gives_ratio_one(model: float) -> None:
    """At most ``stationary`` x the merit (here 1e-8 of 10) predicted: nothing to judge by."""
    ratio = step_ratio(10.0, 12.0, model, 1e-9)
    assert ratio.value == 1.0
    assert ratio.actual == -2.0


def test_the_stationary_scale_is_at_least_one() -> None:
    """A merit near zero does not make every step stationary: its scale is 1."""
    assert step_ratio(1e-12, 0.0, -0.5, 1e-9).value == pytest.approx(2e-12, rel=1e-9)
    assert step_ratio(0.0, 0.0, -5e-10, 1e-9).value == 1.0


@pytest.mark.parametrize(
    ("ratio", "verdict"),
    [
        (-0.1, Verdict.REJECT),
        (0.0, Verdict.SHRINK),
        (0.2, Verdict.SHRINK),
        (0.25, Verdict.KEEP),
        (0.7, Verdict.KEEP),
        (0.75, Verdict.GROW),
    ],
)
def test_verdicts_follow_the_thresholds(ratio: float, verdict: Verdict) -> None:
    assert SCVX.verdict(ratio) is verdict


def test_without_a_shrinking_band_a_ratio_is_rejected_or_kept() -> None:
    thresholds = RatioThresholds(reject=0.1, shrink=0.1, grow=0.75)
    assert [thresholds.verdict(r) for r in (0.05, 0.1, 0.5, 0.8)] == [
        Verdict.REJECT,
        Verdict.KEEP,
        Verdict.KEEP,
        Verdict.GROW,
    ]


def test_a_radius_shrinks_and_grows_within_its_bounds() -> None:
    region = TrustRegion(1.0, 0.25, 4.0)
    region.shorten()
    region.shorten()
    region.shorten()
    assert region.size == 0.25  # held at its minimum
    for _ in range(5):
        region.lengthen()
    assert region.size == 4.0 and region.at_longest
    region.at_most_as_long_as(0.5)
    assert region.size == 0.5


def test_a_penalty_weight_moves_the_other_way() -> None:
    region = TrustRegion(1.0, 0.125, 8.0, penalty=True)
    region.shorten(4.0)
    assert region.size == 4.0
    region.shorten(4.0)
    assert region.size == 8.0  # held at its maximum
    region.lengthen(16.0)
    assert region.size == 0.5
    region.lengthen(16.0)
    assert region.size == 0.125 and region.at_longest
    region.at_most_as_long_as(0.25)
    assert region.size == 0.25
