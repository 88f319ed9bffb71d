"""Early detection of a diverging SCP iterate: non-finite numbers or a step no entry trajectory
can take in one iteration, read from the candidate and its history record (SI, degrees)."""

from __future__ import annotations

import dataclasses
from typing import Any

from worker.solver.finite import non_finite_entries
from worker.solver.scp.history import IterationRecord

STEP_BOUNDS: dict[str, float] = {
    "altitude_m": 200e3,
    "velocity_m_s": 5e3,
    "longitude_deg": 90.0,
    "latitude_deg": 90.0,
    "flight_path_angle_deg": 90.0,
    "heading_deg": 90.0,
}
"""Largest change of a state over the nodes in one iteration that is still a step, not a
divergence. 200 km is more than the whole entry corridor (the entry interface near 120 km to the
ground): no two iterates of an entry trajectory can differ by more. 5 km/s is two thirds of the
orbital speed an entry starts from. 90 deg is a quarter of the globe in longitude or latitude, a
quarter turn of heading, and the whole range of one sign of the flight-path angle: either
method's trust region moves these by a few degrees per iteration (the largest step of the
recorded test cases is 19 deg, at the first iteration from the guess). Controls carried as
states (bank, angle of attack) are bounded by their limits and may reverse legitimately; they
are not bounded here. States not listed are only checked for finiteness."""


def _non_finite(value: Any) -> bool:
    """Whether ``value`` (a number, an array, a dict or list of them) holds NaN or infinity."""
    return bool(non_finite_entries(value))


def non_finite_fields(candidate: Any) -> list[str]:
    """The fields of a candidate reference (a dataclass of arrays, numbers and dicts of them)
    that hold NaN or infinity; empty for anything else."""
    if not dataclasses.is_dataclass(candidate) or isinstance(candidate, type):
        return []
    return [
        f.name for f in dataclasses.fields(candidate) if _non_finite(getattr(candidate, f.name))
    ]


def divergence(candidate: Any, record: IterationRecord) -> str | None:
    """Why the proposal of ``record`` diverged (naming the state, the iteration and the size),
    or None when it is a step: non-finite candidate fields or state changes, or a state change
    over its ``STEP_BOUNDS``."""
    it = record.iteration
    bad = non_finite_fields(candidate)
    if bad:
        return f"iteration {it}: the candidate holds non-finite values ({', '.join(bad)})"
    change = record.max_state_change
    non_finite = [name for name, v in change.items() if _non_finite(v)]
    if non_finite:
        return f"iteration {it}: non-finite change of {', '.join(non_finite)}"
    over = [
        (name, float(change[name]), bound)
        for name, bound in STEP_BOUNDS.items()
        if name in change and abs(change[name]) > bound
    ]
    if not over:
        return None
    parts = ", ".join(f"{name} by {size:.4g} (bound {bound:g})" for name, size, bound in over)
    return f"iteration {it}: the step changed {parts} in one iteration"
