"""How several objective terms combine: the caller's weighted sum in the terms' own units (s, m/s,
deg, J/m^2), whatever each method's internal normalization of a term alone."""

from __future__ import annotations

from collections.abc import Sequence


def term_pulls(weights: Sequence[float], units: Sequence[float]) -> list[float]:
    """The weight of each objective term on its method-normalized value (value / unit, ``unit``
    the term's value in its own SI unit per normalized unit): a single term keeps its weight; of
    several, term i gets kappa w_i unit_i with kappa = max w / max (w unit), so the objective is
    kappa times the caller's weighted sum in SI units (the weights trade those units, as the
    contract says) and its strongest term pulls per normalized unit as hard as the largest
    weight. Normalizing each term by its own unit instead would re-weight a combination."""
    if len(weights) == 1:
        return [float(weights[0])]
    kappa = max(weights) / max(w * u for w, u in zip(weights, units, strict=True))
    return [kappa * w * u for w, u in zip(weights, units, strict=True)]


def weighted_sum(values: dict[str, float], weights: dict[str, float]) -> float | None:
    """sum of weight x value over the terms, max terms negated (what the methods minimize, in
    the terms' own units: s, m/s, deg, J/m^2); None when a term's value is missing."""
    if set(values) != set(weights):
        return None
    return sum((-1.0 if n.startswith("max") else 1.0) * weights[n] * v for n, v in values.items())
