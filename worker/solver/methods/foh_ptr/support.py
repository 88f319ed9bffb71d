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
    spherical_only_issues,
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
    out.extend(_final_time_issues(doc))
    out.extend(_alpha_issues(doc))
    if doc.waypoints:
        out.append(issue("waypoints", f"{NAME} does not handle waypoints yet"))
    if doc.energy is not None:
        out.append(
            issue("energy", f"{NAME} works in time and ignores energy bounds; leave energy out")
        )
    out.extend(spherical_only_issues(doc, NAME))
    out.extend(objective_issues(doc, NAME, OBJECTIVES, "optimize"))
    options = doc.method
    if isinstance(options, FohPtrOptions):
        out.extend(_grid_issues(doc, options))
    return out


def _alpha_issues(doc: ProblemDocument) -> list[FieldIssue]:
    """A scheduled angle of attack is flown as given; an optimized one, or a parabolic polar's
    normalized lift, becomes a second held state (its rate a second control) on the exact FOH
    discretization only."""
    attack = doc.vehicle.angle_of_attack
    polar = doc.vehicle.aerodynamics.model == "parabolic_polar"
    if not polar and (attack is None or attack.mode != "optimized"):
        return scheduled_alpha_issues(doc, NAME)
    out = []
    if polar and doc.control_limits.alpha_rate_max_deg_s is not None:
        out.append(
            issue(
                "control_limits.alpha_rate_max_deg_s",
                f"{NAME} flies a polar's normalized lift, which has no angle of attack to limit",
            )
        )
    options = doc.method
    if isinstance(options, FohPtrOptions) and options.discretization != "exact_foh":
        out.append(
            issue(
                "method.discretization",
                f"{NAME} holds an optimized angle of attack or normalized lift on the "
                '"exact_foh" discretization only; leave discretization out',
            )
        )
    return out


def _final_time_issues(doc: ProblemDocument) -> list[FieldIssue]:
    """A free final time needs the adaptive grid (its interval lengths carry the flight time)
    and a terminal altitude or speed to end the flight."""
    options = doc.method
    if doc.final_time.kind == "fixed":
        return []
    out = []
    if isinstance(options, FohPtrOptions) and options.grid != "adaptive":
        out.append(
            issue(
                "method.grid",
                f"{NAME} flies a free final time on the adaptive grid (its interval lengths "
                'sum to the flight time); use grid "adaptive" or a fixed final time',
            )
        )
    ends = (doc.terminal.altitude_m, doc.terminal.velocity_m_s)
    if all(spec.target() is None for spec in ends):
        out.append(
            issue(
                "final_time",
                f"{NAME}: a free final time needs a terminal altitude or speed to end the "
                "flight; give terminal.altitude_m",
            )
        )
    return out


PAPER_INTERVALS_S = (10.0, 150.0, 50.0)
"""Paper 002's Delta_min, Delta_max and DeltaT_max (sec. 4), for its 39 intervals of 1600 s."""
PAPER_MEAN_INTERVAL_S = 1600.0 / 39


def grid_factor(options: FohPtrOptions, span_s: float) -> float:
    """The mean interval span / N over paper 002's (1600 s / 39): 1 at the paper's 40 nodes."""
    return (span_s / (options.nodes - 1)) / PAPER_MEAN_INTERVAL_S


def interval_bounds(options: FohPtrOptions, span_s: float) -> tuple[float, float, float]:
    """(Delta_min, Delta_max, DeltaT_max) in s over a flight of ``span_s``: each given value, or
    paper 002's as the same multiple of the mean interval span / N (the paper's own at 40 nodes
    over 1600 s), so that any node count spans the flight."""
    factor = grid_factor(options, span_s)
    given = (options.interval_min_s, options.interval_max_s, options.interval_trust_s)
    lo, hi, trust = (
        g if g is not None else p * factor for g, p in zip(given, PAPER_INTERVALS_S, strict=True)
    )
    return lo, hi, trust


def _grid_issues(doc: ProblemDocument, options: FohPtrOptions) -> list[FieldIssue]:
    """Given interval bounds that contradict each other or cannot span the flight time, named
    by the given field (the derived defaults are consistent by construction)."""
    if doc.final_time.kind != "fixed" or options.grid != "adaptive":
        return []
    span = doc.final_time.value_s - doc.initial_state.time_s
    n = options.nodes - 1
    lo, hi, _ = interval_bounds(options, span)
    given_lo, given_hi = options.interval_min_s is not None, options.interval_max_s is not None
    if lo > hi:
        field = "method.interval_min_s" if given_lo else "method.interval_max_s"
        return [
            issue(
                field,
                f"interval_min_s {lo:g} exceeds interval_max_s {hi:g}"
                + ("" if given_lo and given_hi else " (the other is derived from t_f / N)"),
                "inconsistent",
            )
        ]
    if n * lo > span:
        return [
            issue(
                "method.interval_min_s",
                f"{n} intervals of at least {lo:g} s exceed the flight time {span:g} s; lower "
                f"interval_min_s to at most {span / n:g} or leave it out",
                "inconsistent",
            )
        ]
    if n * hi < span:
        return [
            issue(
                "method.interval_max_s",
                f"{n} intervals of at most {hi:g} s cannot span the flight time {span:g} s; "
                f"raise interval_max_s to at least {span / n:g} or leave it out",
                "inconsistent",
            )
        ]
    return []
