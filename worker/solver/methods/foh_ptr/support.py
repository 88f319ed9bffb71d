"""What paper 002's time-domain FOH method cannot express, and the consistency of its grid:
refused with a field path and a reason before any work is done."""

from __future__ import annotations

from app.schemas import FieldIssue, ProblemDocument
from app.schemas.methods import FohPtrOptions
from worker.solver.methods.base import (
    FINAL_EXTREMES,
    issue,
    objective_issues,
    scheduled_alpha_issues,
)

NAME = "foh-ptr"
OBJECTIVES = (
    "max_terminal_velocity",
    "min_heat_load",
    *FINAL_EXTREMES,
)


def check_support(doc: ProblemDocument) -> list[FieldIssue]:
    """Features the time-domain FOH method cannot express, and grid consistency."""
    out: list[FieldIssue] = []
    if doc.final_time.kind != "fixed":
        out.append(
            issue(
                "final_time",
                f"{NAME} needs a fixed final time (its grid is time with interval lengths "
                'summing to it); give final_time {"kind": "fixed", "value_s": ...}',
            )
        )
    out.extend(scheduled_alpha_issues(doc, NAME))
    if doc.waypoints:
        out.append(issue("waypoints", f"{NAME} does not handle waypoints yet"))
    if doc.energy is not None:
        out.append(
            issue("energy", f"{NAME} works in time and ignores energy bounds; leave energy out")
        )
    out.extend(objective_issues(doc, NAME, OBJECTIVES, "optimize"))
    options = doc.method
    if isinstance(options, FohPtrOptions):
        out.extend(_grid_issues(doc, options))
    return out


def _grid_issues(doc: ProblemDocument, options: FohPtrOptions) -> list[FieldIssue]:
    """Interval bounds that contradict each other or cannot span the flight time."""
    out = []
    lo, hi = options.interval_min_s, options.interval_max_s
    if lo > hi:
        out.append(
            issue(
                "method.interval_min_s",
                f"interval_min_s {lo:g} exceeds interval_max_s {hi:g}",
                "inconsistent",
            )
        )
    if doc.final_time.kind == "fixed":
        span = doc.final_time.value_s - doc.initial_state.time_s
        n = options.nodes - 1
        if options.grid == "adaptive" and not n * lo <= span <= n * hi:
            out.append(
                issue(
                    "method.nodes",
                    f"{n} intervals of {lo:g}..{hi:g} s cannot span the flight time "
                    f"{span:g} s; change nodes or the interval bounds",
                    "inconsistent",
                )
            )
    return out
