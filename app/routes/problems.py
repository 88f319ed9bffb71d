"""``POST /v1/problems/validate``: check a problem without solving it."""

from __future__ import annotations

from fastapi import APIRouter

from app.body import ProblemBody, problem_request_body
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
    openapi_extra=problem_request_body(VALIDATE_EXAMPLES),
)
def validate_problem(
    body: ProblemBody,
    settings: SettingsDep,
) -> ValidationReport:
    """All errors at once (422), or the normalized document with defaults filled in and the
    legal values far outside what entry vehicles fly listed as warnings (200)."""
    submission = resolve_submission(body)
    check_server_caps(submission.problem, settings)
    check_method_support(submission)
    return ValidationReport(problem=submission.document, warnings=submission.warnings())
