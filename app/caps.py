"""Server caps on what one job may ask for: nodes, iterations, time limit, zones, waypoints.

They sit below the contract's own maxima (``app.schemas.limits``) and are set by the operator;
a problem over a cap is a 422 whose issue names the cap and its setting.
"""

from __future__ import annotations

from typing import Any

from app.errors import ApiError
from app.schemas import FieldIssue, ProblemDocument
from app.settings import Settings


def _over(field: str, value: Any, cap: float, setting: str, *, given: bool = True) -> FieldIssue:
    """The issue of ``field`` over ``cap``; a method's default over it says so and what to give."""
    if given:
        message = f"{value} exceeds the server cap {setting}={cap:g}"
    else:
        message = (
            f"the method's default {value} exceeds the server cap {setting}={cap:g}; give "
            f"{field} at most {cap:g}"
        )
    return FieldIssue(field=field, message=message, code="server_cap")


def cap_issues(problem: ProblemDocument, settings: Settings) -> list[FieldIssue]:
    """Every field of ``problem`` over a server cap (empty when all are within)."""
    issues: list[FieldIssue] = []
    method = problem.method
    given = method.model_fields_set
    checks: list[tuple[str, float, float, str]] = [
        ("method.nodes", method.nodes, settings.max_nodes, "TRAJOPT_MAX_NODES"),
        (
            "method.max_iterations",
            method.max_iterations,
            settings.max_iterations,
            "TRAJOPT_MAX_ITERATIONS",
        ),
        (
            "method.time_limit_s",
            method.time_limit_s,
            settings.max_time_limit_s,
            "TRAJOPT_MAX_TIME_LIMIT_S",
        ),
    ]
    for field, value, cap, setting in checks:
        if value > cap:
            name = field.split(".")[-1]
            issues.append(_over(field, value, cap, setting, given=name in given))
    for i, count in enumerate(getattr(method, "phase_nodes", None) or []):
        if count > settings.max_nodes:
            field = f"method.phase_nodes.{i}"
            issues.append(_over(field, count, settings.max_nodes, "TRAJOPT_MAX_NODES"))
    zones = len(problem.no_fly_zones)
    if zones > settings.max_no_fly_zones:
        issues.append(
            _over(
                "no_fly_zones",
                f"{zones} zones",
                settings.max_no_fly_zones,
                "TRAJOPT_MAX_NO_FLY_ZONES",
            )
        )
    waypoints = len(problem.waypoints)
    if waypoints > settings.max_waypoints:
        issues.append(
            _over(
                "waypoints",
                f"{waypoints} waypoints",
                settings.max_waypoints,
                "TRAJOPT_MAX_WAYPOINTS",
            )
        )
    return issues


def check_server_caps(problem: ProblemDocument, settings: Settings) -> None:
    """422 ``over_server_cap`` listing every field over a server cap."""
    issues = cap_issues(problem, settings)
    if not issues:
        return
    first = issues[0]
    raise ApiError(
        422,
        "over_server_cap",
        f"the problem exceeds {len(issues)} server cap(s); first: {first.field}: {first.message}",
        field=first.field,
        issues=[i.model_dump() for i in issues],
    )
