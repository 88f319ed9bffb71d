"""Server caps on what one job may ask for: nodes, iterations, time limit, zones, waypoints.

They sit below the contract's own maxima (``app.schemas.limits``) and are set by the operator;
a problem over a cap is a 422 whose issue names the cap and its setting.
"""

from __future__ import annotations

from typing import Any

from app.errors import ApiError
from app.schemas import AutoOptions, FieldIssue, ProblemDocument
from app.schemas.methods import ScpRunOptions
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
    """Every field of ``problem`` over a server cap (empty when all are within); for auto, its
    time limit and node count, and each method's options as auto would run them."""
    method = problem.method
    if isinstance(method, AutoOptions):
        issues = _auto_issues(problem, method, settings)
    else:
        issues = _method_issues(method, settings, "method", method.model_fields_set)
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


_CAPPED = (
    ("nodes", "max_nodes", "TRAJOPT_MAX_NODES"),
    ("max_iterations", "max_iterations", "TRAJOPT_MAX_ITERATIONS"),
    ("time_limit_s", "max_time_limit_s", "TRAJOPT_MAX_TIME_LIMIT_S"),
)
"""Each capped option of a method: its name, the setting's attribute and its variable."""


def _method_issues(
    method: ScpRunOptions,
    settings: Settings,
    prefix: str,
    given: set[str],
    options: tuple[str, ...] = ("nodes", "max_iterations", "time_limit_s"),
) -> list[FieldIssue]:
    """``options`` of one method over a server cap (``given``: the options the user wrote)."""
    issues: list[FieldIssue] = []
    for name, attribute, setting in _CAPPED:
        value, cap = getattr(method, name), getattr(settings, attribute)
        if name in options and value > cap:
            issues.append(_over(f"{prefix}.{name}", value, cap, setting, given=name in given))
    for i, count in enumerate(getattr(method, "phase_nodes", None) or []):
        if count > settings.max_nodes:
            field = f"{prefix}.phase_nodes.{i}"
            issues.append(_over(field, count, settings.max_nodes, "TRAJOPT_MAX_NODES"))
    return issues


def _auto_issues(
    problem: ProblemDocument, auto: AutoOptions, settings: Settings
) -> list[FieldIssue]:
    """Auto's own budget and nodes over a cap, then the options of each method that accepts
    the problem as auto would run it: its iterations, its nodes unless auto's ``nodes`` set
    them, its time limit only when overridden (otherwise it is what auto's budget leaves)."""
    from worker.solver.methods.selection import select  # the solver's registry, loaded on use

    given = auto.model_fields_set
    issues: list[FieldIssue] = []
    if auto.time_limit_s > settings.max_time_limit_s:
        issues.append(
            _over(
                "method.time_limit_s",
                auto.time_limit_s,
                settings.max_time_limit_s,
                "TRAJOPT_MAX_TIME_LIMIT_S",
                given="time_limit_s" in given,
            )
        )
    if auto.nodes is not None and auto.nodes > settings.max_nodes:
        issues.append(_over("method.nodes", auto.nodes, settings.max_nodes, "TRAJOPT_MAX_NODES"))
    for candidate in select(problem).candidates:
        own = set(auto.overrides.get(candidate.name, {}))
        checked = ["max_iterations"]
        if auto.nodes is None or "nodes" in own:
            checked.append("nodes")
        if "time_limit_s" in own:
            checked.append("time_limit_s")
        prefix = f"method.overrides.{candidate.name}"
        issues += _method_issues(candidate.options, settings, prefix, own, tuple(checked))
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
