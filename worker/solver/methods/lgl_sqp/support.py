"""What paper 004's evolutionary collocation cannot express: refused with a field path and a
reason before any work is done."""

from __future__ import annotations

from app.schemas import FieldIssue, ProblemDocument
from worker.solver.methods.base import (
    FINAL_EXTREMES,
    issue,
    objective_issues,
    polar_issues,
    spherical_only_issues,
)

NAME = "lgl-sqp"
OBJECTIVES = ("min_propellant", "min_time", "max_terminal_velocity", *FINAL_EXTREMES)


def check_support(doc: ProblemDocument) -> list[FieldIssue]:
    """Features the method cannot express."""
    out: list[FieldIssue] = []
    attack = doc.vehicle.angle_of_attack
    if attack is None or attack.mode != "optimized":
        out.append(
            issue(
                "vehicle.angle_of_attack",
                f"{NAME} optimizes the angle of attack as a control; give "
                '{"mode": "optimized", "min_deg": ..., "max_deg": ...}',
            )
        )
    out += polar_issues(doc, NAME)
    for field, given in (
        ("control_limits.bank_rate_max_deg_s", doc.control_limits.bank_rate_max_deg_s),
        ("control_limits.alpha_rate_max_deg_s", doc.control_limits.alpha_rate_max_deg_s),
    ):
        if given is not None:
            out.append(issue(field, f"{NAME} flies alpha and bank as controls without rate limits"))
    if attack is not None and getattr(attack, "rate_max_deg_s", None) is not None:
        out.append(
            issue(
                "vehicle.angle_of_attack.rate_max_deg_s",
                f"{NAME} flies alpha as a control without a rate limit",
            )
        )
    if doc.no_fly_zones:
        out.append(issue("no_fly_zones", f"{NAME} does not handle no-fly zones yet"))
    if doc.waypoints:
        out.append(issue("waypoints", f"{NAME} does not handle waypoints yet"))
    if doc.energy is not None:
        out.append(issue("energy", f"{NAME} works in time; leave energy out"))
    if doc.initial_guess is not None:
        out.append(
            issue(
                "initial_guess",
                f"{NAME} makes its own guess: method.initial_guess (global or constant) and "
                "method.global_guess (algorithm, seed, budget)",
            )
        )
    ends = [("terminal", doc.terminal)] + [
        (f"phases[{i}].end", phase.end) for i, phase in enumerate(doc.phases)
    ]
    for where, conditions in ends:
        for name, spec in conditions:
            if getattr(spec, "kind", None) == "soft":
                out.append(
                    issue(f"{where}.{name}", f"{NAME} takes fixed, range or free end conditions")
                )
    if doc.initial_state.bank_deg is not None:
        out.append(
            issue("initial_state.bank_deg", f"{NAME} leaves the initial bank free (a control)")
        )
    out.extend(spherical_only_issues(doc, NAME))
    out.extend(objective_issues(doc, NAME, OBJECTIVES, "optimize"))
    return out
