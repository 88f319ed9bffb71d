"""Turn a submitted body into a validated problem: a problem document, or a scenario + overrides.

All problems are collected and reported together (422) with dotted field paths.
"""

from __future__ import annotations

import copy
import hashlib
import json
from dataclasses import dataclass
from typing import Any

from pydantic import ValidationError

from app.errors import ApiError
from app.schemas import FieldIssue, ProblemDocument, issues_from_validation_error
from app.views import ScenarioJobRequest


@dataclass(frozen=True)
class Submission:
    """A validated problem ready to store."""

    problem: ProblemDocument
    document: dict[str, Any]
    scenario: str | None

    @property
    def method(self) -> str:
        """Name of the selected solution method."""
        return str(self.problem.method.name)


def deep_merge(base: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    """``base`` with ``overrides`` merged in: objects merge key by key, other values replace."""
    merged = copy.deepcopy(base)
    for key, value in overrides.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            merged[key] = deep_merge(merged[key], value)
        else:
            merged[key] = copy.deepcopy(value)
    return merged


def request_fingerprint(body: Any) -> str:
    """SHA-256 of the body's canonical JSON (key order and spacing do not matter)."""
    canonical = json.dumps(body, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(canonical.encode()).hexdigest()


def invalid(issues: list[FieldIssue], what: str = "problem") -> ApiError:
    """The 422 error listing every issue."""
    first = issues[0] if issues else None
    message = f"the {what} has {len(issues)} error(s)"
    if first is not None:
        message += f"; first: {first.field or '(document)'}: {first.message}"
    return ApiError(
        422,
        f"invalid_{what}",
        message,
        field=first.field if first else None,
        issues=[i.model_dump() for i in issues],
    )


def _scenario_document(body: dict[str, Any]) -> tuple[dict[str, Any], str]:
    from worker.solver.scenarios import get_scenario

    try:
        request = ScenarioJobRequest.model_validate(body)
    except ValidationError as exc:
        raise invalid(issues_from_validation_error(exc), "request") from None
    try:
        scenario = get_scenario(request.scenario)
    except KeyError as exc:
        issue = FieldIssue(field="scenario", message=str(exc.args[0]), code="unknown_scenario")
        raise invalid([issue], "request") from None
    document = deep_merge(scenario.problem, request.overrides)
    if request.method is not None:
        document = deep_merge(document, {"method": request.method})
    return document, scenario.name


def resolve_submission(body: Any) -> Submission:
    """Validate ``body`` (problem document or scenario request); raises a 422 ``ApiError``."""
    if not isinstance(body, dict):
        issue = FieldIssue(field="", message="the body must be a JSON object", code="dict_type")
        raise invalid([issue], "request")
    scenario: str | None = None
    document = body
    if "scenario" in body:
        document, scenario = _scenario_document(body)
    try:
        problem = ProblemDocument.model_validate(document)
    except ValidationError as exc:
        raise invalid(issues_from_validation_error(exc)) from None
    return Submission(problem=problem, document=problem.model_dump(mode="json"), scenario=scenario)


def check_method_support(submission: Submission) -> None:
    """422 when the selected method cannot handle a feature the problem uses."""
    from worker.solver.methods import check_support

    issues = check_support(submission.problem)
    if issues:
        raise invalid(list(issues))
