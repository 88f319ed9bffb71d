"""What a pre-check found: the input that binds, its figure, and what to change."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Finding:
    """One binding input. ``proven``: a necessary condition of every solution fails (the problem
    has none, whatever the method); otherwise the figure makes the input the likely cause of a
    failure. ``value`` is what the flight or the geometry reaches, ``limit`` what the input
    asks, both in ``units``."""

    check: str
    """limit_below_pull_up, zone_covers_entry, zone_covers_target, zone_blocks_corridor,
    target_out_of_reach or final_time."""
    field: str
    """The problem field to change, as a path (path_constraints.heat_rate.max_W_m2)."""
    message: str
    advice: str
    proven: bool
    value: float | None = None
    limit: float | None = None
    units: str | None = None
    possible: bool = False
    """The figure allows a solution the held flights do not show: a possible cause only, which
    names the input but does not call a failed run infeasible."""

    def as_cause(self) -> dict[str, Any]:
        """The result's ``failure.cause`` record."""
        return {
            "check": self.check,
            "field": self.field,
            "proven": self.proven,
            "value": self.value,
            "limit": self.limit,
            "units": self.units,
            "likely": not self.possible,
        }
