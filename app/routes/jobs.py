"""``/v1/jobs``: submit, list, show, cancel, and read the problem, the result and the history of
jobs."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, BackgroundTasks, Query, Response

from app import jobs_service
from app.body import ProblemBody, problem_request_body
from app.deps import DatabaseDep, DispatcherDep, OwnerDep, SettingsDep, SubmitterDep
from app.routes.accepted import IdempotencyKey, accepted
from app.routes.examples import (
    HISTORY_EXAMPLES,
    PROBLEM_DOCUMENT_EXAMPLES,
    PROBLEM_EXAMPLES,
    RESULT_EXAMPLES,
)
from app.views import ErrorResponse, HistoryView, JobPage, JobStatusName, JobView

router = APIRouter(prefix="/v1/jobs", tags=["jobs"])

COMPONENTS = "#/components/schemas"
_NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"model": ErrorResponse}}


@router.post(
    "",
    status_code=202,
    response_model=JobView,
    summary="Submit a job",
    responses={
        202: {"description": "Stored and queued; poll the Location."},
        404: {
            "model": ErrorResponse,
            "description": "initial_guess.from_job is not one of your jobs.",
        },
        413: {"model": ErrorResponse, "description": "The body is over the size limit."},
        422: {"model": ErrorResponse, "description": "Every invalid field, or a server cap."},
        429: {
            "model": ErrorResponse,
            "description": "Rate limit, or too many queued and running jobs; see Retry-After.",
        },
        503: {
            "model": ErrorResponse,
            "description": "The queue is unreachable; nothing was stored, retry after Retry-After.",
        },
    },
    openapi_extra=problem_request_body(PROBLEM_EXAMPLES),
)
def submit_job(
    body: ProblemBody,
    response: Response,
    background: BackgroundTasks,
    database: DatabaseDep,
    dispatcher: DispatcherDep,
    settings: SettingsDep,
    owner: SubmitterDep,
    idempotency_key: IdempotencyKey = None,
) -> JobView:
    """Store a problem document (or a scenario with overrides) and queue it for solving."""
    view, replayed = jobs_service.submit_job(
        database=database,
        dispatcher=dispatcher,
        settings=settings,
        owner=owner,
        body=body,
        idempotency_key=idempotency_key,
        defer=background.add_task,
    )
    accepted(response, view.links.self, replayed)
    return view


@router.get("", response_model=JobPage, summary="List your jobs")
def list_jobs(
    database: DatabaseDep,
    settings: SettingsDep,
    owner: OwnerDep,
    status: Annotated[
        list[JobStatusName] | None, Query(description="Only these statuses (repeatable).")
    ] = None,
    limit: Annotated[int, Query(ge=1, le=100)] = 20,
    offset: Annotated[int, Query(ge=0, le=1_000_000_000)] = 0,
) -> JobPage:
    """The caller's jobs, newest first, optionally filtered by status."""
    statuses = [str(s) for s in status] if status else None
    return jobs_service.list_jobs(database, settings, owner, statuses, limit, offset)


@router.get("/{job_id}", response_model=JobView, responses=_NOT_FOUND, summary="Show a job")
def get_job(job_id: str, database: DatabaseDep, settings: SettingsDep, owner: OwnerDep) -> JobView:
    """Status, timestamps, attempts and live progress (updated every SCP iteration)."""
    return jobs_service.get_job(database, settings, owner, job_id)


@router.get(
    "/{job_id}/result",
    response_class=Response,
    responses={
        200: {
            "description": "The result document of the solver.",
            "content": {
                "application/json": {
                    "schema": {"$ref": f"{COMPONENTS}/ResultDocument"},
                    "examples": RESULT_EXAMPLES,
                }
            },
        },
        **_NOT_FOUND,
        409: {
            "model": ErrorResponse,
            "description": "Not finished yet, or finished without a result document.",
        },
    },
    summary="Fetch the result document",
)
def get_result(job_id: str, database: DatabaseDep, owner: OwnerDep) -> Response:
    """The full result document of a finished job (409 while queued or running)."""
    return Response(jobs_service.get_result(database, owner, job_id), media_type="application/json")


@router.get(
    "/{job_id}/problem",
    response_class=Response,
    responses={
        200: {
            "description": "The problem document the job solves, normalized (every default "
            "filled in) after its scenario, overrides and start were applied; its SHA-256 in "
            "canonical JSON is the result's provenance.problem_sha256.",
            "content": {
                "application/json": {
                    "schema": {"$ref": f"{COMPONENTS}/ProblemDocument"},
                    "examples": PROBLEM_DOCUMENT_EXAMPLES,
                }
            },
        },
        **_NOT_FOUND,
    },
    summary="Fetch the problem as solved",
)
def get_problem(job_id: str, database: DatabaseDep, owner: OwnerDep) -> Response:
    """The problem document the job solves, as stored (available from submission on)."""
    return Response(
        jobs_service.get_problem(database, owner, job_id), media_type="application/json"
    )


@router.get(
    "/{job_id}/history",
    response_model=HistoryView,
    response_model_exclude_unset=True,  # each record as stored, no null added by the model
    responses={
        200: {
            "description": "The iterations so far.",
            "content": {"application/json": {"examples": HISTORY_EXAMPLES}},
        },
        **_NOT_FOUND,
    },
    summary="Convergence history",
)
def get_history(job_id: str, database: DatabaseDep, owner: OwnerDep) -> HistoryView:
    """Per-iteration records so far; available while the job runs."""
    return jobs_service.get_history(database, owner, job_id)


@router.delete(
    "/{job_id}",
    response_model=JobView,
    responses={
        200: {"description": "Cancelled (it had not started)."},
        202: {"model": JobView, "description": "Running: stops at its next iteration."},
        **_NOT_FOUND,
        409: {"model": ErrorResponse, "description": "Already finished."},
    },
    summary="Cancel a job",
)
def cancel_job(
    job_id: str,
    response: Response,
    database: DatabaseDep,
    settings: SettingsDep,
    owner: OwnerDep,
) -> JobView:
    """Cancel a queued job at once; a running job stops at its next iteration, keeping history."""
    view, status = jobs_service.cancel_job(database, settings, owner, job_id)
    response.status_code = status
    return view
