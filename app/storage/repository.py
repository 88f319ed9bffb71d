"""Repository functions over the ``jobs`` table.

Every status change is one conditional ``UPDATE ... WHERE status IN (...)`` whose row count says
whether it happened, so concurrent or duplicated deliveries can never move a job backwards or
overwrite a finished one. Worker writes are also fenced by the attempt number they claimed.
"""

from __future__ import annotations

import uuid
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from sqlalchemy import Text, case, cast, func, select, update
from sqlalchemy.orm import Session

from app.storage.models import ACTIVE_STATUSES, Job, JobStatus, utcnow

_NO_SYNC = {"synchronize_session": False}


@dataclass(frozen=True)
class NewJob:
    """What the API stores when a job is submitted."""

    owner: str
    method: str
    problem: dict[str, Any]
    scenario: str | None = None
    idempotency_key: str | None = None
    request_hash: str | None = None


def create_job(session: Session, new: NewJob) -> Job:
    """Insert a ``queued`` job and flush it (raises ``IntegrityError`` on a duplicate key)."""
    now = utcnow()
    job = Job(
        id=str(uuid.uuid4()),
        owner=new.owner,
        status=JobStatus.QUEUED.value,
        method=new.method,
        scenario=new.scenario,
        problem=new.problem,
        idempotency_key=new.idempotency_key,
        request_hash=new.request_hash,
        attempts=0,
        cancel_requested=False,
        created_at=now,
        updated_at=now,
        history=[],
    )
    session.add(job)
    session.flush()
    return job


def get_job(session: Session, job_id: str, owner: str | None = None) -> Job | None:
    """The job ``job_id`` (only if it belongs to ``owner`` when one is given)."""
    stmt = select(Job).where(Job.id == job_id)
    if owner is not None:
        stmt = stmt.where(Job.owner == owner)
    return session.execute(stmt).scalar_one_or_none()


@dataclass(frozen=True)
class ResultText:
    """A job's status and error with its result document as stored JSON text (not parsed)."""

    status: str
    error_code: str | None
    error_message: str | None
    result_json: str | None


def get_result_text(session: Session, job_id: str, owner: str) -> ResultText | None:
    """The owner's job result as JSON text, read without decoding it."""
    row = session.execute(
        select(Job.status, Job.error_code, Job.error_message, cast(Job.result, Text)).where(
            Job.id == job_id, Job.owner == owner
        )
    ).one_or_none()
    if row is None:
        return None
    status, code, message, text = row
    return ResultText(status, code, message, text if text not in (None, "null") else None)


def find_by_idempotency_key(session: Session, owner: str, key: str) -> Job | None:
    """The owner's job submitted with ``key``, if any."""
    stmt = select(Job).where(Job.owner == owner, Job.idempotency_key == key)
    return session.execute(stmt).scalar_one_or_none()


def list_jobs(
    session: Session,
    owner: str,
    statuses: Sequence[str] | None = None,
    limit: int = 20,
    offset: int = 0,
) -> tuple[list[Job], int]:
    """A page of the owner's jobs, newest first, and the total number matching."""
    conditions = [Job.owner == owner]
    if statuses:
        conditions.append(Job.status.in_(list(statuses)))
    total = session.execute(select(func.count()).select_from(Job).where(*conditions)).scalar_one()
    stmt = (
        select(Job)
        .where(*conditions)
        .order_by(Job.created_at.desc(), Job.id.desc())
        .limit(limit)
        .offset(offset)
    )
    return list(session.execute(stmt).scalars()), int(total)


def transition(
    session: Session,
    job_id: str,
    *,
    to: str,
    allowed_from: Iterable[str],
    attempt: int | None = None,
    values: dict[str, Any] | None = None,
) -> bool:
    """Move ``job_id`` to status ``to`` only if it is in ``allowed_from``; True if it moved."""
    now = utcnow()
    fields: dict[str, Any] = {"status": to, "updated_at": now, **(values or {})}
    if to not in ACTIVE_STATUSES:
        fields.setdefault("finished_at", now)
    stmt = update(Job).where(Job.id == job_id, Job.status.in_(list(allowed_from)))
    if attempt is not None:
        stmt = stmt.where(Job.attempts == attempt)
    result = session.execute(stmt.values(**fields).execution_options(**_NO_SYNC))
    return _rowcount(result) == 1


class ClaimState(StrEnum):
    """Why a delivery may or may not run a job."""

    CLAIMED = "claimed"
    MISSING = "missing"
    FINISHED = "finished"
    EXHAUSTED = "exhausted"
    CANCELLED = "cancelled"


@dataclass(frozen=True)
class Claim:
    """Outcome of :func:`claim_attempt`: the state and, when claimed, the attempt number."""

    state: ClaimState
    attempt: int = 0
    problem: dict[str, Any] | None = field(default=None, compare=False)


def claim_attempt(session: Session, job_id: str, max_attempts: int) -> Claim:
    """Atomically count one more attempt and mark the job ``running``, unless it must not run.

    A delivery of a finished job does nothing; one beyond ``max_attempts`` ends the job as
    ``failed``/``worker_lost``; one of a running job whose cancel was requested ends it as
    ``cancelled`` (its previous worker died before it could).
    """
    now = utcnow()
    stmt = (
        update(Job)
        .where(
            Job.id == job_id,
            Job.status.in_([JobStatus.QUEUED.value, JobStatus.RUNNING.value]),
            Job.attempts < max_attempts,
            Job.cancel_requested.is_(False),
        )
        .values(
            status=JobStatus.RUNNING.value,
            attempts=Job.attempts + 1,
            started_at=now,
            updated_at=now,
            progress=None,
            history=[],
        )
        .returning(Job.attempts, Job.problem)
        .execution_options(**_NO_SYNC)
    )
    claimed = session.execute(stmt).one_or_none()
    if claimed is not None:
        return Claim(ClaimState.CLAIMED, int(claimed[0]), claimed[1])
    job = session.execute(
        select(Job.status, Job.attempts, Job.cancel_requested).where(Job.id == job_id)
    ).one_or_none()
    if job is None:
        return Claim(ClaimState.MISSING)
    status, attempts, cancel_requested = job
    if status not in ACTIVE_STATUSES:
        return Claim(ClaimState.FINISHED, int(attempts))
    if cancel_requested:
        transition(
            session,
            job_id,
            to=JobStatus.CANCELLED.value,
            allowed_from=ACTIVE_STATUSES,
            values={"error_code": "cancelled", "error_message": "cancelled on request"},
        )
        return Claim(ClaimState.CANCELLED, int(attempts))
    transition(
        session,
        job_id,
        to=JobStatus.FAILED.value,
        allowed_from=ACTIVE_STATUSES,
        values={
            "error_code": "worker_lost",
            "error_message": (
                f"the job was started {attempts} times and its worker was lost each time; giving up"
            ),
        },
    )
    return Claim(ClaimState.EXHAUSTED, int(attempts))


def record_iteration(
    session: Session,
    job_id: str,
    attempt: int,
    history: list[dict[str, Any]],
    progress: dict[str, Any],
) -> bool:
    """Store the history so far and the live progress of a running attempt; False if not ours."""
    stmt = (
        update(Job)
        .where(Job.id == job_id, Job.status == JobStatus.RUNNING.value, Job.attempts == attempt)
        .values(history=history, progress=progress, updated_at=utcnow())
        .execution_options(**_NO_SYNC)
    )
    return _rowcount(session.execute(stmt)) == 1


def should_stop(session: Session, job_id: str, attempt: int) -> bool:
    """True when a cancel was requested or the attempt no longer owns the job."""
    row = session.execute(
        select(Job.status, Job.attempts, Job.cancel_requested).where(Job.id == job_id)
    ).one_or_none()
    if row is None:
        return True
    status, attempts, cancel_requested = row
    return bool(cancel_requested) or status != JobStatus.RUNNING.value or attempts != attempt


def request_cancel(session: Session, job_id: str, owner: str) -> Job | None:
    """Cancel a queued job at once, or flag a running one to stop; returns the job after."""
    now = utcnow()
    session.execute(
        update(Job)
        .where(Job.id == job_id, Job.owner == owner, Job.status == JobStatus.QUEUED.value)
        .values(
            status=JobStatus.CANCELLED.value,
            cancel_requested=True,
            finished_at=now,
            updated_at=now,
            error_code="cancelled",
            error_message="cancelled on request before it started",
        )
        .execution_options(**_NO_SYNC)
    )
    session.execute(
        update(Job)
        .where(Job.id == job_id, Job.owner == owner, Job.status == JobStatus.RUNNING.value)
        .values(cancel_requested=True, updated_at=now)
        .execution_options(**_NO_SYNC)
    )
    session.expire_all()
    return get_job(session, job_id, owner)


def active_job_ids(session: Session) -> list[str]:
    """Ids of jobs still queued or running, oldest first (for re-dispatch after a restart)."""
    stmt = (
        select(Job.id).where(Job.status.in_(list(ACTIVE_STATUSES))).order_by(Job.created_at, Job.id)
    )
    return list(session.execute(stmt).scalars())


def count_by_status(session: Session) -> dict[str, int]:
    """Number of jobs in each status (every status present, zero if none)."""
    counts = {status.value: 0 for status in JobStatus}
    for status, count in session.execute(select(Job.status, func.count()).group_by(Job.status)):
        counts[str(status)] = int(count)
    return counts


@dataclass(frozen=True)
class HistogramData:
    """Cumulative bucket counts (one per upper bound), the sum and the count of observations."""

    bounds: tuple[float, ...]
    cumulative: tuple[int, ...]
    total: float
    count: int


def solve_time_histogram(session: Session, bounds: Sequence[float]) -> HistogramData:
    """Histogram of the stored solve times of finished jobs, for the Prometheus endpoint."""
    columns: list[Any] = [func.count(Job.solve_s), func.coalesce(func.sum(Job.solve_s), 0.0)]
    columns += [func.coalesce(func.sum(case((Job.solve_s <= b, 1), else_=0)), 0) for b in bounds]
    row = session.execute(select(*columns).where(Job.solve_s.is_not(None))).one()
    count, total, *cumulative = row
    return HistogramData(
        bounds=tuple(bounds),
        cumulative=tuple(int(c) for c in cumulative),
        total=float(total),
        count=int(count),
    )


def _rowcount(result: Any) -> int:
    return int(getattr(result, "rowcount", 0) or 0)
