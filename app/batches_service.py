"""Batches: submit many jobs on one base problem at once, follow them as one, summarize them.

A batch is validated whole before anything is stored: the request, the base problem, every
child (a refusal names the child, its parameters and the field). Its children are ordinary
jobs: stored with the batch in one transaction, each queued like a single submission (its own
outbox entry, so the relay sends any the submitting request could not), counted against the
client's active-job cap, ranked for the fair share after the client's other active jobs. A
batch uses one unit of the client's submission window.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import logging
from collections.abc import Callable
from typing import Any

from pydantic import ValidationError
from sqlalchemy.exc import IntegrityError

from app.batch_plan import PointerError, batch_size, expand
from app.caps import cap_issues
from app.dispatch import Dispatcher
from app.dispatch.fair import priority_of_rank
from app.errors import MAX_ISSUES, ApiError, not_found
from app.jobs_service import (
    ACTIVE_CAP_RETRY_AFTER_S,
    check_idempotency_key,
    check_replay,
    mark_sent,
    resolve_initial_guess,
)
from app.ratelimit import Quota, Submitter
from app.report.batch import summary_csv, summary_row
from app.schemas import FieldIssue, issues_from_validation_error
from app.schemas.batch import BatchRequest
from app.settings import Settings
from app.storage import quota as quota_store
from app.storage import repository
from app.storage.models import ACTIVE_STATUSES, Batch
from app.storage.session import Database
from app.submission import Submission, invalid, request_fingerprint, resolve_submission
from app.views import BatchLinks, BatchPage, BatchSummary, BatchView
from worker.limits import job_time_limits

log = logging.getLogger(__name__)

GroundTrack = tuple[list[float], list[float]]
SummaryPlotInputs = tuple[str, list[dict[str, Any]], list[str], list[GroundTrack]]
"""A batch plot's kind, summary rows, parameter paths and flown ground tracks."""


def batch_location(batch_id: str) -> str:
    """The batch's URL path."""
    return f"/v1/batches/{batch_id}"


def batch_view(batch: Batch, counts: dict[str, int]) -> BatchView:
    """The API's view of a batch with its children's counts per status."""
    active = sum(counts.get(s, 0) for s in ACTIVE_STATUSES)
    status = "running" if active else ("cancelled" if batch.cancel_requested else "finished")
    base = batch_location(batch.id)
    return BatchView(
        id=batch.id,
        name=batch.name,
        kind=batch.kind,
        size=batch.size,
        status=status,
        counts=counts,
        cancel_requested=batch.cancel_requested,
        created_at=batch.created_at,
        links=BatchLinks(
            self=base,
            summary=f"{base}/summary",
            summary_csv=f"{base}/summary.csv",
            plot=f"{base}/plot.png",
        ),
    )


def _prefixed(issues: list[FieldIssue], prefix: str, note: str = "") -> list[FieldIssue]:
    return [
        FieldIssue(
            field=f"{prefix}.{i.field}" if i.field else prefix,
            message=f"{i.message}{note}",
            code=i.code,
        )
        for i in issues
    ]


def _parse(body: Any) -> BatchRequest:
    try:
        return BatchRequest.model_validate(body)
    except ValidationError as exc:
        issues = issues_from_validation_error(exc, limit=MAX_ISSUES)
        raise invalid(issues, "batch", total=exc.error_count()) from None


def _api_issues(exc: ApiError) -> list[FieldIssue]:
    listed = exc.issues or [{"field": exc.field or "", "message": exc.message, "code": exc.code}]
    return [FieldIssue(field=i["field"], message=i["message"], code=i["code"]) for i in listed]


def _pointer_field(request: BatchRequest, pointer: str) -> str:
    """The request field that holds ``pointer`` (the first grid parameter or dispersion)."""
    if request.grid is not None:
        paths = [p.path for p in request.grid.parameters]
        return f"grid.parameters[{paths.index(pointer)}].path" if pointer in paths else "grid"
    if request.monte_carlo is not None:
        paths = [d.path for d in request.monte_carlo.dispersions]
        where = f"[{paths.index(pointer)}].path" if pointer in paths else ""
        return f"monte_carlo.dispersions{where}"
    return "footprint" if request.footprint is not None else "methods"


def plan_children(
    request: BatchRequest,
    settings: Settings,
    resolve: Callable[[Submission], Submission] = lambda submission: submission,
) -> list[repository.NewJob]:
    """The validated children of ``request`` as jobs to store (owner left empty); a 422
    naming every bad child (index, parameters, field) otherwise. ``resolve`` completes an
    initial guess given by ``from_job`` (the base's, or one a child's parameters set) with
    that job's trajectory, as for a single job; a job not the caller's is a 404."""
    from worker.solver.methods import check_support  # the solver's registry, loaded on use

    size = batch_size(request)
    field = {
        "grid": "grid",
        "monte_carlo": "monte_carlo.samples",
        "methods": "methods",
        "footprint": "footprint.longitudes_deg",
    }
    if size > settings.max_batch_children:
        issue = FieldIssue(
            field=field[request.kind],
            message=f"the batch has {size} children; the server's cap is "
            f"{settings.max_batch_children} (TRAJOPT_MAX_BATCH_CHILDREN)",
            code="over_server_cap",
        )
        raise ApiError(
            422, "over_server_cap", issue.message, field=issue.field, issues=[issue.model_dump()]
        )
    try:
        base = resolve_submission(request.base)
        resolve(base)  # the base's own from_job, refused here at "base"
    except ApiError as exc:
        if exc.status == 404:  # the base's from_job is not the caller's
            raise
        raise invalid(_prefixed(_api_issues(exc), "base"), "batch") from None
    try:  # on the base as given: each child resolves its own from_job
        children = expand(request, base.document)
    except PointerError as exc:
        issue = FieldIssue(
            field=_pointer_field(request, exc.pointer), message=str(exc), code="bad_pointer"
        )
        raise invalid([issue], "batch") from None
    planned: list[repository.NewJob] = []
    issues: list[FieldIssue] = []
    for child in children:
        note = f" (child {child.index}: {json.dumps(child.parameters)})"
        try:
            submission = resolve(resolve_submission(child.document))
        except ApiError as exc:
            if exc.status == 404:  # a from_job that is not the caller's
                where = f"children[{child.index}].{exc.field}"
                raise ApiError(404, exc.code, f"{where}: {exc.message}", field=where) from None
            issues += _prefixed(_api_issues(exc), f"children[{child.index}]", note)
            continue
        problems = cap_issues(submission.problem, settings) + list(
            check_support(submission.problem)
        )
        if problems:
            issues += _prefixed(list(problems), f"children[{child.index}]", note)
            continue
        planned.append(
            repository.NewJob(
                owner="",
                method=submission.method,
                problem=submission.document,
                scenario=base.scenario,
                batch_parameters=child.parameters,
                warnings=submission.stored_warnings(),
                overrides=base.patches,
            )
        )
    if issues:
        raise invalid(issues[:MAX_ISSUES], "batch", total=len(issues))
    return planned


def submit_batch(
    *,
    database: Database,
    dispatcher: Dispatcher,
    settings: Settings,
    owner: str,
    body: Any,
    idempotency_key: str | None,
    defer: Callable[[Callable[[], None]], None] | None = None,
) -> tuple[BatchView, bool]:
    """Validate, store and dispatch a batch; its view and whether it was a replay."""
    quota: Quota | None = owner.quota if isinstance(owner, Submitter) else None
    owner = str(owner)
    idempotency_key = check_idempotency_key(idempotency_key)
    fingerprint = request_fingerprint(body) if idempotency_key else None
    if idempotency_key:
        with database.reader() as session:
            existing = repository.find_batch_by_idempotency_key(session, owner, idempotency_key)
            if existing is not None:
                return _replay(session, existing, fingerprint, idempotency_key), True
    refusal = quota.check("submit") if quota is not None else None
    if refusal is not None:
        raise ApiError(429, "rate_limited", refusal.message, headers=refusal.headers)
    try:
        request = _parse(body)
        children = plan_children(
            request, settings, functools.partial(resolve_initial_guess, database, owner, known={})
        )
    except ApiError:
        if quota is not None:
            quota.note_rejected()
        raise
    new = repository.NewBatch(
        owner=owner,
        kind=request.kind,
        request=request.model_dump(mode="json", exclude_none=True),
        size=len(children),
        name=request.name,
        idempotency_key=idempotency_key,
        request_hash=fingerprint,
    )
    try:
        with database.session() as session:
            active = quota_store.locked_active_count(session, owner)
            _check_room(active, len(children), settings)
            refusal = quota.charge("submit") if quota is not None else None
            if refusal is not None:
                raise ApiError(429, "rate_limited", refusal.message, headers=refusal.headers)
            owned = [dataclasses.replace(child, owner=owner) for child in children]
            batch, jobs = repository.create_batch(session, new, owned)
            view = batch_view(batch, {"queued": len(jobs)})
    except IntegrityError:
        if not idempotency_key:
            raise
        with database.reader() as session:  # a concurrent request with the same key won
            existing = repository.find_batch_by_idempotency_key(session, owner, idempotency_key)
            if existing is None:
                raise
            return _replay(session, existing, fingerprint, idempotency_key), True
    _dispatch(database, dispatcher, settings, jobs, active, defer)
    log.info("batch %s of %d jobs accepted for client %s", batch.id, len(jobs), owner)
    return view, False


def _check_room(active: int, size: int, settings: Settings) -> None:
    """The children count towards the client's active-job cap: 422 if the batch could never
    fit, 429 (retry later) if it does not fit now."""
    cap = settings.max_active_jobs
    if size > cap:
        raise ApiError(
            422,
            "over_server_cap",
            f"the batch has {size} children, more than the {cap} queued or running jobs a "
            "client may have (TRAJOPT_MAX_ACTIVE_JOBS)",
            field="size",
            issues=[{"field": "size", "message": f"{size} > {cap}", "code": "over_server_cap"}],
        )
    if active + size > cap:
        raise ApiError(
            429,
            "too_many_active_jobs",
            f"client has {active} queued or running jobs; {size} more would pass the cap of "
            f"{cap} (TRAJOPT_MAX_ACTIVE_JOBS)",
            headers={"Retry-After": str(ACTIVE_CAP_RETRY_AFTER_S)},
        )


def _dispatch(
    database: Database,
    dispatcher: Dispatcher,
    settings: Settings,
    jobs: list[Any],
    active: int,
    defer: Callable[[Callable[[], None]], None] | None,
) -> None:
    """Queue each child (ranked after the client's other active jobs); a child the queue
    refuses stays due in the outbox, which the relay sends later."""
    for rank, job in enumerate(jobs, start=active):
        try:
            dispatcher.submit(
                job.id, job_time_limits(job.problem, settings), priority_of_rank(rank)
            )
        except Exception as exc:
            log.warning("batch child %s not queued now (the relay will): %s", job.id, exc)
            return
        if defer is not None:
            defer(functools.partial(mark_sent, database, job.id))
        else:
            mark_sent(database, job.id)


def _replay(session: Any, existing: Batch, fingerprint: str | None, key: str) -> BatchView:
    check_replay(existing.request_hash, fingerprint, key)
    return batch_view(existing, repository.batch_counts(session, [existing.id])[existing.id])


def get_batch(database: Database, owner: str, batch_id: str) -> BatchView:
    """The batch with its children's counts; 404 if it is not the owner's."""
    with database.reader() as session:
        batch = repository.get_batch(session, batch_id, owner)
        if batch is None:
            raise not_found("batch", batch_id)
        return batch_view(batch, repository.batch_counts(session, [batch.id])[batch.id])


def list_batches(database: Database, owner: str, limit: int, offset: int) -> BatchPage:
    """A page of the owner's batches, newest first."""
    with database.reader() as session:
        batches, total = repository.list_batches(session, owner, limit, offset)
        counts = repository.batch_counts(session, [b.id for b in batches])
        items = [batch_view(b, counts[b.id]) for b in batches]
    following = offset + len(items)
    return BatchPage(
        items=items,
        total=total,
        limit=limit,
        offset=offset,
        next_offset=following if following < total else None,
    )


def cancel_batch(database: Database, owner: str, batch_id: str) -> BatchView:
    """Cancel every child not finished yet (queued at once, running at its next iteration)."""
    with database.session() as session:
        batch = repository.cancel_batch(session, batch_id, owner)
        if batch is None:
            raise not_found("batch", batch_id)
    return get_batch(database, owner, batch_id)


def parameter_paths(batch: Batch) -> list[str]:
    """The batch's parameter paths, in column order."""
    request = batch.request
    if batch.kind == "grid":
        return [p["path"] for p in request["grid"]["parameters"]]
    if batch.kind == "monte_carlo":
        return [d["path"] for d in request["monte_carlo"]["dispersions"]]
    if batch.kind == "footprint":
        return ["/terminal/longitude_deg", "/objective"]
    return ["/method"]


def summary(database: Database, owner: str, batch_id: str) -> BatchSummary:
    """One row per child, in order (rows of unfinished children say so)."""
    with database.reader() as session:
        batch = repository.get_batch(session, batch_id, owner)
        if batch is None:
            raise not_found("batch", batch_id)
        view = batch_view(batch, repository.batch_counts(session, [batch.id])[batch.id])
        rows = [
            summary_row(c.index, c.id, c.parameters, c.status, c.error_code, c.result)
            for c in repository.batch_children(session, batch_id, owner)
        ]
        paths = parameter_paths(batch)
    return BatchSummary(batch=view, parameters=paths, rows=rows)


def summary_table(database: Database, owner: str, batch_id: str) -> str:
    """The summary as CSV."""
    table = summary(database, owner, batch_id)
    return summary_csv(table.rows, table.parameters)


def plot_state(database: Database, owner: str, batch_id: str) -> str:
    """A digest of what the batch's plot depends on (its children's statuses, and when each
    finished one last changed): the plot kept under it is rendered again once a child moves."""
    with database.reader() as session:
        if repository.get_batch(session, batch_id, owner) is None:
            raise not_found("batch", batch_id)
        state = repository.batch_children_state(session, batch_id, owner)
    return hashlib.sha256(repr(state).encode()).hexdigest()


def plot_inputs(database: Database, owner: str, batch_id: str) -> SummaryPlotInputs:
    """What :func:`app.report.batch.render_summary_plot` draws the batch's plot from (all but
    the format); a footprint's with each child's flown ground track."""
    table = summary(database, owner, batch_id)
    tracks: list[GroundTrack] = []
    if table.batch.kind == "footprint":
        with database.reader() as session:
            children = repository.batch_children(session, batch_id, owner, repository.TRACK_PARTS)
            for child in children:
                flown = ((child.result or {}).get("verification") or {}).get("propagated") or {}
                if child.status == "succeeded" and flown.get("longitude_deg"):
                    tracks.append((flown["longitude_deg"], flown["latitude_deg"]))
    return table.batch.kind, table.rows, table.parameters, tracks
