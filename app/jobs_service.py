"""The job use cases behind the routes: submit, show, list, cancel, problem, result and
history."""

from __future__ import annotations

import dataclasses
import functools
import json
import logging
from collections.abc import Callable
from datetime import datetime
from typing import Any

from pydantic import ValidationError
from sqlalchemy.exc import IntegrityError

from app.caps import check_server_caps
from app.dispatch import Dispatcher
from app.dispatch.fair import priority_of_rank
from app.errors import ApiError, not_found
from app.ratelimit import Quota, Submitter
from app.schemas import FieldIssue
from app.schemas.guess import guess_columns
from app.schemas.plausibility import PlausibilityWarning
from app.settings import Settings
from app.storage import quota as quota_store
from app.storage import repository
from app.storage.models import ACTIVE_STATUSES, Job, JobStatus, utcnow
from app.storage.session import Database
from app.submission import (
    Submission,
    check_method_support,
    invalid,
    request_fingerprint,
    resolve_submission,
)
from app.views import HistoryView, JobErrorInfo, JobLinks, JobPage, JobView, Progress
from worker.limits import job_time_limits

log = logging.getLogger(__name__)

MAX_IDEMPOTENCY_KEY_LENGTH = 255
ACTIVE_CAP_RETRY_AFTER_S = 10
"""Retry-After of a submission refused because the client has too many active jobs."""
QUEUE_RETRY_AFTER_S = 5
"""Retry-After of a submission refused because the queue is unreachable."""


def job_location(job_id: str) -> str:
    """The URL path of a job."""
    return f"/v1/jobs/{job_id}"


def job_view(job: Job, settings: Settings, now: datetime | None = None) -> JobView:
    """The API representation of a stored job."""
    now = now or utcnow()
    elapsed = None
    if job.started_at is not None:
        end = job.finished_at if job.status not in ACTIVE_STATUSES and job.finished_at else now
        elapsed = max(0.0, (end - job.started_at).total_seconds())
    error = JobErrorInfo(code=job.error_code, message=job.error_message) if job.error_code else None
    base = job_location(job.id)
    return JobView(
        id=job.id,
        status=job.status,
        owner=job.owner,
        method=job.method,
        scenario=job.scenario,
        attempts=job.attempts,
        max_attempts=settings.max_attempts,
        cancel_requested=job.cancel_requested,
        created_at=job.created_at,
        updated_at=job.updated_at,
        started_at=job.started_at,
        finished_at=job.finished_at,
        elapsed_s=elapsed,
        progress=_progress(job),
        error=error,
        solve_s=job.solve_s,
        warnings=_warnings(job),
        links=JobLinks(
            self=base,
            result=f"{base}/result",
            history=f"{base}/history",
            events=f"{base}/events",
            problem=f"{base}/problem",
        ),
    )


def _warnings(job: Job) -> list[PlausibilityWarning]:
    """The plausibility warnings stored with the job (none for a job stored before them)."""
    try:
        return [PlausibilityWarning.model_validate(w) for w in job.warnings or []]
    except ValidationError:  # an unexpected record shape must not hide the job
        log.warning("job %s: unreadable warnings %r", job.id, job.warnings)
        return []


def _progress(job: Job) -> Progress | None:
    """The stored progress; a terminal job's says ``finished`` (its last iteration's figures
    kept), however the job ended (by its worker, a cancel while queued, the sweeper)."""
    progress = None
    if job.progress:
        try:
            progress = Progress.model_validate(job.progress)
        except ValidationError:  # an unexpected record shape must not hide the job
            log.warning("job %s: unreadable progress %r", job.id, job.progress)
    if job.status in ACTIVE_STATUSES:
        return progress
    return (progress or Progress()).model_copy(update={"phase": "finished"})


def check_idempotency_key(key: str | None) -> str | None:
    """``key`` if it is a usable Idempotency-Key (None: none given); 422 otherwise."""
    if key is None:
        return None
    if not key or len(key) > MAX_IDEMPOTENCY_KEY_LENGTH or not key.isprintable():
        raise ApiError(
            422,
            "invalid_idempotency_key",
            f"Idempotency-Key must be 1..{MAX_IDEMPOTENCY_KEY_LENGTH} printable characters",
            field="Idempotency-Key",
        )
    return key


def check_replay(stored_hash: str | None, fingerprint: str | None, key: str) -> None:
    """422 when Idempotency-Key ``key`` was first used with another body."""
    if stored_hash != fingerprint:
        raise ApiError(
            422,
            "idempotency_key_reused",
            f"Idempotency-Key {key!r} was already used with a different body",
            field="Idempotency-Key",
        )


def _replay(existing: Job, fingerprint: str, key: str) -> Job:
    check_replay(existing.request_hash, fingerprint, key)
    return existing


def _replayed(job: Job, settings: Settings, quota: Quota | None) -> JobView:
    """The view of a replayed job; a replay costs a read, not a submission."""
    refusal = quota.charge("read") if quota is not None else None
    if refusal is not None:
        raise ApiError(429, "rate_limited", refusal.message, headers=refusal.headers)
    return job_view(job, settings)


def submit_job(
    *,
    database: Database,
    dispatcher: Dispatcher,
    settings: Settings,
    owner: str,
    body: Any,
    idempotency_key: str | None,
    defer: Callable[[Callable[[], None]], None] | None = None,
) -> tuple[JobView, bool]:
    """Validate, store and dispatch a job; returns its view and whether it was a replay.

    ``defer`` (the route's background tasks) takes the closing of the job's outbox entry, which
    the answer need not wait for (if it never runs, the relay sends the job again and the
    duplicate does nothing); without it that write is made before returning.

    ``owner`` is the client's name; when it is a :class:`Submitter` (as the route gives it),
    a replay costs one read, a new submission needs room in the submit window (429 before
    validation otherwise) and uses one unit of it only when accepted, and a refusal with a
    4xx uses one unit of the rejected-submission window instead.
    """
    quota = owner.quota if isinstance(owner, Submitter) else None
    owner = str(owner)
    try:
        key = check_idempotency_key(idempotency_key)
        fingerprint = request_fingerprint(body) if key else None
        if key and fingerprint:
            with database.reader() as session:
                existing = repository.find_by_idempotency_key(session, owner, key)
            if existing is not None:
                return _replayed(_replay(existing, fingerprint, key), settings, quota), True
    except ApiError as exc:
        if quota is not None and exc.status == 422:  # a bad key, or a key reused: rejected
            quota.note_rejected()
        raise
    refusal = quota.check("submit") if quota is not None else None
    if refusal is not None:  # the cheap answer: no validation, no unit used
        raise ApiError(429, "rate_limited", refusal.message, headers=refusal.headers)
    try:
        return _submit(database, dispatcher, settings, owner, body, key, fingerprint, quota, defer)
    except ApiError as exc:
        if quota is not None and 400 <= exc.status < 500:
            quota.note_rejected()
        raise


def _submit(
    database: Database,
    dispatcher: Dispatcher,
    settings: Settings,
    owner: str,
    body: Any,
    key: str | None,
    fingerprint: str | None,
    quota: Quota | None,
    defer: Callable[[Callable[[], None]], None] | None = None,
) -> tuple[JobView, bool]:
    """:func:`submit_job` for a request that is no replay; every refusal is an ApiError."""
    submission = resolve_initial_guess(database, owner, resolve_submission(body))
    check_server_caps(submission.problem, settings)
    check_method_support(submission)
    new = repository.NewJob(
        owner=owner,
        method=submission.method,
        problem=submission.document,
        scenario=submission.scenario,
        idempotency_key=key,
        request_hash=fingerprint,
        warnings=submission.stored_warnings(),
        overrides=submission.patches,
    )
    try:
        with database.session() as session:
            # The client's submissions pass one at a time from here to the commit, so the
            # count is exact: the cap cannot be overshot by submissions in flight.
            active = quota_store.locked_active_count(session, owner)
            if key and fingerprint:  # the same key may have been stored since the look-up
                existing = repository.find_by_idempotency_key(session, owner, key)
                if existing is not None:
                    replayed = _replay(existing, fingerprint, key)
                    return _replayed(replayed, settings, quota), True
            if active >= settings.max_active_jobs:
                raise ApiError(
                    429,
                    "too_many_active_jobs",
                    f"client has {active} queued or running jobs; the cap is "
                    f"{settings.max_active_jobs} (TRAJOPT_MAX_ACTIVE_JOBS)",
                    headers={"Retry-After": str(ACTIVE_CAP_RETRY_AFTER_S)},
                )
            refusal = quota.charge("submit") if quota is not None else None
            if refusal is not None:  # lost the race for the last units of the window
                raise ApiError(429, "rate_limited", refusal.message, headers=refusal.headers)
            job = repository.create_job(session, new)
            # under the client's submission lock every other active job of the client is
            # older: the new job's fair-share rank is their count (dispatch_rank, without
            # a second transaction)
            priority = priority_of_rank(active)
    except IntegrityError:
        if not (key and fingerprint):
            raise
        with database.session() as session:  # a concurrent request with the same key won
            existing = repository.find_by_idempotency_key(session, owner, key)
        if existing is None:
            raise
        return _replayed(_replay(existing, fingerprint, key), settings, quota), True

    try:
        limits = job_time_limits(submission.document, settings)
        dispatcher.submit(job.id, limits, priority)
    except Exception as exc:
        log.warning(
            "job %s of client %s could not be queued: %s: %s",
            job.id,
            owner,
            type(exc).__name__,
            exc,
        )
        with database.session() as session:
            withdrawn = repository.withdraw_unclaimed(session, job.id)
        if withdrawn:  # never accepted: the client retries (same Idempotency-Key is safe)
            raise ApiError(
                503,
                "queue_unavailable",
                "the queue is unreachable; nothing was stored, retry later",
                headers={"Retry-After": str(QUEUE_RETRY_AFTER_S)},
            ) from exc
        log.info("job %s was picked up despite the error; accepted", job.id)
    else:
        if defer is not None:
            defer(functools.partial(mark_sent, database, job.id))
        else:
            mark_sent(database, job.id)
    log.info("job %s accepted for client %s (%s)", job.id, owner, job.method)
    return job_view(job, settings), False


def resolve_initial_guess(
    database: Database,
    owner: str,
    submission: Submission,
    known: dict[str, dict[str, list[float]]] | None = None,
) -> Submission:
    """A submission whose ``initial_guess.from_job`` names one of the owner's finished jobs
    with a trajectory, with that trajectory copied into the guess (the stored problem then
    carries it; a later change of that job changes nothing). 404 for a job that is not the
    owner's, 422 for one without a usable trajectory. ``known``: trajectories already read,
    by job id (a batch reads each job once for all its children)."""
    guess = submission.problem.initial_guess
    if guess is None or guess.from_job is None or guess.trajectory is not None:
        return submission
    columns = known.get(guess.from_job) if known is not None else None
    if columns is None:
        columns = _guess_trajectory(database, owner, guess.from_job)
        if known is not None:
            known[guess.from_job] = columns
    document = {
        **submission.document,
        "initial_guess": {"from_job": guess.from_job, "trajectory": columns},
    }
    resolved = resolve_submission(document)  # a scenario job keeps its scenario and patches
    return dataclasses.replace(resolved, scenario=submission.scenario, patches=submission.patches)


def _guess_trajectory(database: Database, owner: str, job_id: str) -> dict[str, list[float]]:
    """The trajectory columns of the owner's job ``job_id`` a guess takes (404 if the job is
    not the owner's, 422 without a complete trajectory)."""
    field = "initial_guess.from_job"
    with database.reader() as session:
        found = repository.get_result_text(session, job_id, owner)
    if found is None:
        raise ApiError(404, "job_not_found", f"no job {job_id!r}", field=field)
    result = json.loads(found.result_json) if found.result_json is not None else {}
    columns = guess_columns(result.get("trajectory") or {})
    if columns is None:
        issue = FieldIssue(
            field=field,
            message=f"job {job_id} ({found.status}) has no complete trajectory to start from",
            code="no_trajectory",
        )
        raise invalid([issue])
    return columns


def mark_sent(database: Database, job_id: str) -> None:
    """Close the job's outbox entry; if this fails, the relay sends the job once more (a
    duplicate delivery does nothing)."""
    try:
        with database.autocommit() as session:  # one conditional UPDATE
            repository.mark_dispatched(session, job_id)
    except Exception:
        log.warning("job %s: could not record that it was sent", job_id, exc_info=True)


def _load(database: Database, owner: str, job_id: str) -> Job:
    with database.reader() as session:
        job = repository.get_job(session, job_id, owner)
    if job is None:
        raise not_found("job", job_id)
    return job


def get_job(database: Database, settings: Settings, owner: str, job_id: str) -> JobView:
    """The owner's job or 404."""
    return job_view(_load(database, owner, job_id), settings)


def list_jobs(
    database: Database,
    settings: Settings,
    owner: str,
    statuses: list[str] | None,
    limit: int,
    offset: int,
) -> JobPage:
    """A page of the owner's jobs, newest first."""
    with database.reader() as session:
        jobs, total = repository.list_jobs(session, owner, statuses, limit, offset)
    now = utcnow()
    next_offset = offset + len(jobs) if offset + len(jobs) < total else None
    return JobPage(
        items=[job_view(j, settings, now) for j in jobs],
        total=total,
        limit=limit,
        offset=offset,
        next_offset=next_offset,
    )


def get_result(database: Database, owner: str, job_id: str) -> str:
    """The stored result document as JSON text; 409 while not finished or if there is none."""
    with database.reader() as session:
        found = repository.get_result_text(session, job_id, owner)
    if found is None:
        raise not_found("job", job_id)
    if found.status in ACTIVE_STATUSES:
        raise ApiError(
            409, "job_not_finished", f"job {job_id} is {found.status}; its result is not ready"
        )
    if found.result_json is None:
        reason = f": {found.error_code}: {found.error_message}" if found.error_code else ""
        raise ApiError(
            409,
            "result_unavailable",
            f"job {job_id} ended {found.status} without a result{reason}",
        )
    return found.result_json


def get_problem(database: Database, owner: str, job_id: str) -> str:
    """The owner's job's problem document as solved, as stored JSON text; 404 otherwise."""
    with database.reader() as session:
        text = repository.get_problem_text(session, job_id, owner)
    if text is None:
        raise not_found("job", job_id)
    return text


def get_history(database: Database, owner: str, job_id: str) -> HistoryView:
    """The convergence history so far."""
    job = _load(database, owner, job_id)
    return HistoryView(job_id=job.id, status=job.status, iterations=list(job.history or []))


def cancel_job(
    database: Database, settings: Settings, owner: str, job_id: str
) -> tuple[JobView, int]:
    """Cancel a queued job now (200) or ask a running one to stop (202); 409 if finished."""
    with database.session() as session:
        job = repository.request_cancel(session, job_id, owner)
    if job is None:
        raise not_found("job", job_id)
    if job.status == JobStatus.RUNNING:
        return job_view(job, settings), 202
    if job.status == JobStatus.CANCELLED:
        return job_view(job, settings), 200
    raise ApiError(409, "job_finished", f"job {job_id} already ended {job.status}")
