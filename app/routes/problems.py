"""``POST /v1/problems/validate``: check a problem without solving it."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Body

from app.caps import check_server_caps
from app.deps import SettingsDep
from app.routes.examples import VALIDATE_EXAMPLES
from app.submission import check_method_support, resolve_submission
from app.views import ErrorResponse, ValidationReport

router = APIRouter(prefix="/v1/problems", tags=["problems"])


@router.post(
    "/validate",
    response_model=ValidationReport,
    responses={422: {"model": ErrorResponse, "description": "Every invalid field, listed."}},
    summary="Validate a problem",
    openapi_extra={"x-problem-body": True},
)
def validate_problem(
    body: Annotated[dict[str, Any], Body(openapi_examples=VALIDATE_EXAMPLES)],
    settings: SettingsDep,
) -> ValidationReport:
    """All errors at once (422), or the normalized document with defaults filled in (200)."""
    submission = resolve_submission(body)
    check_server_caps(submission.problem, settings)
    check_method_support(submission)
    return ValidationReport(problem=submission.document)
