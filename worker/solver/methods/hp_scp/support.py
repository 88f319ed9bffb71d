"""What paper 003's hp pseudospectral SCP cannot express: refused with a field path and a reason
before any work is done."""

from __future__ import annotations

from app.schemas import FieldIssue, ProblemDocument
from worker.solver.methods.base import (
    FINAL_EXTREMES,
    issue,
    objective_issues,
    polar_issues,
    spherical_only_issues,
)

NAME = "hp-scp"
OBJECTIVES = ("min_time", "max_terminal_velocity", "min_control_effort", *FINAL_EXTREMES)


def check_support(doc: ProblemDocument) -> list[FieldIssue]:
    """Features the method cannot express."""
    out: list[FieldIssue] = []
    attack = doc.vehicle.angle_of_attack
    if attack is not None and attack.mode != "optimized":
        out.append(
            issue(
                "vehicle.angle_of_attack",
                f"{NAME} optimizes the angle of attack as a state; give "
                '{"mode": "optimized", "min_deg": ..., "max_deg": ...}',
            )
        )
    out += polar_issues(doc, NAME)
    if doc.final_time.kind == "fixed":
        out.append(
            issue(
                "final_time",
                f"{NAME} optimizes a free final time; leave final_time free (its bounds are "
                "not used yet)",
            )
        )
    if doc.waypoints:
        out.append(issue("waypoints", f"{NAME} does not handle waypoints yet"))

    if doc.energy is not None:
        out.append(
            issue("energy", f"{NAME} works in time and ignores energy bounds; leave energy out")
        )
    out.extend(spherical_only_issues(doc, NAME))
    out.extend(objective_issues(doc, NAME, OBJECTIVES, "optimize"))
    return out
