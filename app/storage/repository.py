"""Repository functions over the ``jobs`` table.

Every status change is one conditional ``UPDATE ... WHERE status IN (...)`` whose row count says
whether it happened, so concurrent or duplicated deliveries can never move a job backwards or
overwrite a finished one. Worker writes are also fenced by the attempt number they claimed.

The convergence history is stored once, in ``jobs.history``, and only appended to: each write
sends the records the database does not have yet (:func:`record_iteration`,
:func:`complete_history`), and a stored result document keeps an empty ``history`` that
:func:`get_result_text` fills from it (in SQL: the document is served as the database renders it).
"""

from __future__ import annotations

import json
import uuid
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from enum import StrEnum
from typing import Any

from sqlalchemy import (
    String,
    Text,
    and_,
    bindparam,
    case,
    cast,
    delete,
    func,
    literal_column,
    or_,
    select,
    update,
)
from sqlalchemy.dialects.postgresql import JSONB
from sqlalchemy.orm import Session

from app.storage.models import (
    ACTIVE_STATUSES,
    ApiKey,
    Batch,
    Job,
    JobStatus,
    process_identity,
    utcnow,
)

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
    batch_id: str | None = None
    batch_index: int | None = None
    batch_parameters: dict[str, Any] | None = None
    warnings: list[dict[str, Any]] | None = None
    overrides: dict[str, Any] | None = None


DISPATCH_CLAIM_S = 10.0
"""How long a sender holds a queued job's dispatch: if the job is not marked sent by then (the
sender died, or the broker refused), the relay of any API process sends it."""


def create_job(session: Session, new: NewJob) -> Job:
    """Insert a ``queued`` job and flush it (raises ``IntegrityError`` on a duplicate key).

    The row is its own outbox entry: it is due to be sent :data:`DISPATCH_CLAIM_S` from now,
    which gives the submitting request the first try (:func:`mark_dispatched` when it is sent).
    """
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
        dispatch_due_at=now + timedelta(seconds=DISPATCH_CLAIM_S),
        batch_id=new.batch_id,
        batch_index=new.batch_index,
        batch_parameters=new.batch_parameters,
        warnings=new.warnings,
        overrides=new.overrides,
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
    """The owner's job result as JSON text, its ``history`` filled from the job's history.

    The database merges the two and renders the text: the document is neither parsed nor
    serialized here (it can be hundreds of kilobytes), only handed on.
    """
    row = session.execute(
        select(
            Job.status,
            Job.error_code,
            Job.error_message,
            cast(_result_with_history(session), Text),
        ).where(Job.id == job_id, Job.owner == owner)
    ).one_or_none()
    if row is None:
        return None
    status, code, message, text = row
    if text in (None, "null"):
        return ResultText(status, code, message, None)
    return ResultText(status, code, message, text)


def get_problem_text(session: Session, job_id: str, owner: str) -> str | None:
    """The owner's job's problem document as solved, as stored JSON text (not parsed); None
    when there is no such job of ``owner``."""
    text = session.execute(
        select(cast(Job.problem, Text)).where(Job.id == job_id, Job.owner == owner)
    ).scalar_one_or_none()
    return None if text is None else str(text)


def record_solved_problem(
    session: Session, job_id: str, attempt: int, problem: dict[str, Any]
) -> bool:
    """Store the problem the running attempt solves in place of the submitted one (a chained
    batch's child started from a sibling's answer); False if the attempt no longer owns it."""
    stmt = (
        update(Job)
        .where(Job.id == job_id, Job.status == JobStatus.RUNNING.value, Job.attempts == attempt)
        .values(problem=problem)
        .execution_options(**_NO_SYNC)
    )
    return _rowcount(session.execute(stmt)) == 1


def _result_with_history(session: Session) -> Any:
    """SQL for the stored result document with its ``history`` (stored empty, see
    :func:`result_for_storage`) replaced by the job's; a document without one is left alone."""
    if session.get_bind().dialect.name == "postgresql":
        has_history = and_(
            func.jsonb_typeof(Job.result) == "object",
            Job.result.op("?")(bindparam("history_key", "history", type_=String)),
        )
        merged = func.jsonb_set(Job.result, literal_column("'{history}'"), Job.history, False)
        return case((has_history, merged), else_=Job.result)
    return func.json_replace(Job.result, "$.history", func.json(Job.history))


def result_for_storage(result: dict[str, Any] | None) -> dict[str, Any] | None:
    """The result document as stored: its history is kept once, in ``jobs.history``, so the
    document keeps only an empty ``history`` (where it had one) for :func:`get_result_text`."""
    if result is None or "history" not in result:
        return result
    return {**result, "history": []}


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


def _transition_parts(
    job_id: str,
    to: str,
    allowed_from: Iterable[str],
    attempt: int | None,
    values: dict[str, Any] | None,
    unless_cancel_requested: bool,
) -> tuple[list[Any], dict[str, Any]]:
    """The conditions and the new values of moving ``job_id`` to status ``to``."""
    now = utcnow()
    fields: dict[str, Any] = {"status": to, "updated_at": now, **(values or {})}
    if to not in ACTIVE_STATUSES:
        fields.setdefault("finished_at", now)
        fields.setdefault("lease_expires_at", None)
    conditions = [Job.id == job_id, Job.status.in_(list(allowed_from))]
    if attempt is not None:
        conditions.append(Job.attempts == attempt)
    if unless_cancel_requested:
        conditions.append(Job.cancel_requested.is_(False))
    return conditions, fields


def transition(
    session: Session,
    job_id: str,
    *,
    to: str,
    allowed_from: Iterable[str],
    attempt: int | None = None,
    values: dict[str, Any] | None = None,
    unless_cancel_requested: bool = False,
) -> bool:
    """Move ``job_id`` to status ``to`` only if it is in ``allowed_from`` (and, with
    ``unless_cancel_requested``, no cancel was requested); True if it moved."""
    conditions, fields = _transition_parts(
        job_id, to, allowed_from, attempt, values, unless_cancel_requested
    )
    stmt = update(Job).where(*conditions).values(**fields).execution_options(**_NO_SYNC)
    return _rowcount(session.execute(stmt)) == 1


def store_outcome(
    session: Session,
    job_id: str,
    *,
    attempt: int,
    history: Sequence[dict[str, Any]],
    stored: int,
    to: str,
    allowed_from: Iterable[str],
    values: dict[str, Any],
    unless_cancel_requested: bool,
) -> bool:
    """:func:`complete_history` and :func:`transition` of an attempt's outcome in one
    statement, when the stored history holds exactly ``stored`` records (as the attempt's own
    writes say): False when it does not, or when the transition does not apply (the caller
    then takes the two steps, which tell the cases apart)."""
    conditions, fields = _transition_parts(
        job_id, to, allowed_from, attempt, values, unless_cancel_requested
    )
    return _append_at(session, conditions, history, stored, fields)


class ClaimState(StrEnum):
    """Why a delivery may or may not run a job."""

    CLAIMED = "claimed"
    MISSING = "missing"
    BUSY = "busy"
    FINISHED = "finished"
    EXHAUSTED = "exhausted"
    CANCELLED = "cancelled"


@dataclass(frozen=True)
class Claim:
    """Outcome of :func:`claim_attempt`: the state and, when claimed, the attempt number."""

    state: ClaimState
    attempt: int = 0
    problem: dict[str, Any] | None = field(default=None, compare=False)
    batch_id: str | None = None
    batch_parameters: dict[str, Any] | None = field(default=None, compare=False)
    scenario: str | None = None
    overrides: dict[str, Any] | None = field(default=None, compare=False)


def _claimable(now: datetime) -> Any:
    """Queued, or running with a lapsed (or never set) lease: its worker is gone."""
    return or_(
        Job.status == JobStatus.QUEUED.value,
        and_(
            Job.status == JobStatus.RUNNING.value,
            or_(Job.lease_expires_at.is_(None), Job.lease_expires_at < now),
        ),
    )


def claim_attempt(session: Session, job_id: str, max_attempts: int, lease_s: float = 30.0) -> Claim:
    """Atomically count one more attempt and mark the job ``running``, unless it must not run.

    A delivery of a finished job does nothing, and neither does one of a job whose running
    attempt still renews its lease (a duplicate delivery: ``BUSY``). One beyond
    ``max_attempts`` ends the job as ``failed``/``worker_lost``; one of a running job whose
    cancel was requested ends it as ``cancelled`` (its previous worker died before it could).
    """
    now = utcnow()
    stmt = (
        update(Job)
        .where(
            Job.id == job_id,
            _claimable(now),
            Job.attempts < max_attempts,
            Job.cancel_requested.is_(False),
        )
        .values(
            status=JobStatus.RUNNING.value,
            attempts=Job.attempts + 1,
            started_at=now,
            updated_at=now,
            lease_expires_at=now + timedelta(seconds=lease_s),
            lease_holder=process_identity(),
            dispatch_due_at=None,
            progress=None,
            history=[],
        )
        .returning(
            Job.attempts,
            Job.problem,
            Job.batch_id,
            Job.batch_parameters,
            Job.scenario,
            Job.overrides,
        )
        .execution_options(**_NO_SYNC)
    )
    claimed = session.execute(stmt).one_or_none()
    if claimed is not None:
        return Claim(ClaimState.CLAIMED, int(claimed[0]), *claimed[1:])
    job = session.execute(
        select(Job.status, Job.attempts, Job.cancel_requested, Job.lease_expires_at).where(
            Job.id == job_id
        )
    ).one_or_none()
    if job is None:
        return Claim(ClaimState.MISSING)
    status, attempts, cancel_requested, lease = job
    if status not in ACTIVE_STATUSES:
        return Claim(ClaimState.FINISHED, int(attempts))
    if status == JobStatus.RUNNING.value and lease is not None and lease >= now:
        return Claim(ClaimState.BUSY, int(attempts))
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


def _history_length(session: Session) -> Any:
    """SQL for the number of records in ``jobs.history``, in the session's dialect."""
    if session.get_bind().dialect.name == "postgresql":
        return func.jsonb_array_length(Job.history)
    return func.json_array_length(Job.history)


def _appended(session: Session, records: Sequence[dict[str, Any]]) -> Any:
    """SQL for ``jobs.history`` with ``records`` appended (only they are sent)."""
    if session.get_bind().dialect.name == "postgresql":
        return Job.history.op("||")(bindparam("tail", list(records), type_=JSONB))
    pairs: list[Any] = []
    for index, record in enumerate(records):
        pairs += ["$[#]", func.json(bindparam(f"record_{index}", json.dumps(record)))]
    return func.json_insert(Job.history, *pairs)


def _append_history(
    session: Session,
    job_id: str,
    attempt: int,
    records: Sequence[dict[str, Any]],
    statuses: Iterable[str],
    values: dict[str, Any],
    stored: int | None = None,
) -> bool:
    """Append to the job's history the records of ``records`` (the attempt's history so far)
    that it does not hold yet, and set ``values``; fenced by the attempt and ``statuses``.

    The stored length is read first and the write requires it unchanged, so a write that was
    committed although its caller saw an error is never appended twice. A caller that knows
    the length (``stored``: its last write succeeded) saves the read: the write requires that
    length, and only when it does not apply is the length read and the write tried again.
    """
    owned = [Job.id == job_id, Job.status.in_(list(statuses)), Job.attempts == attempt]
    known = stored is not None and stored <= len(records)
    if known and _append_at(session, owned, records, int(stored or 0), values):
        return True
    length = session.execute(select(_history_length(session)).where(*owned)).scalar_one_or_none()
    if length is None:
        return False
    if not values and not records[int(length) :]:
        return True  # nothing to append, and the attempt owns the job
    return _append_at(session, owned, records, int(length), values)


def _append_at(
    session: Session,
    owned: list[Any],
    records: Sequence[dict[str, Any]],
    stored: int,
    values: dict[str, Any],
) -> bool:
    """Set ``values`` and append ``records[stored:]`` if the history holds ``stored`` records."""
    fields = dict(values)
    tail = list(records[stored:])
    if tail:
        fields["history"] = _appended(session, tail)
    if not fields:
        fields["history"] = Job.history  # nothing to change: the row count says if it is owned
    stmt = (
        update(Job)
        .where(*owned, _history_length(session) == stored)
        .values(**fields)
        .execution_options(**_NO_SYNC)
    )
    return _rowcount(session.execute(stmt)) == 1


def record_iteration(
    session: Session,
    job_id: str,
    attempt: int,
    history: Sequence[dict[str, Any]],
    progress: dict[str, Any],
    lease_s: float = 30.0,
    stored: int | None = None,
) -> bool:
    """Append the new records of ``history`` (the attempt's iterations so far) to the stored
    history, store the live progress and renew the lease; False if the attempt no longer owns
    the job. ``stored``: how many records the attempt knows are stored (saves a read)."""
    now = utcnow()
    values = {
        "progress": progress,
        "updated_at": now,
        "lease_expires_at": now + timedelta(seconds=lease_s),
    }
    return _append_history(
        session, job_id, attempt, history, [JobStatus.RUNNING.value], values, stored
    )


def complete_history(
    session: Session,
    job_id: str,
    attempt: int,
    history: Sequence[dict[str, Any]],
    allowed_from: Iterable[str],
) -> bool:
    """Append what the stored history lacks of the attempt's final ``history`` (writes lost
    during the solve), before its outcome is stored; False if the attempt no longer owns it."""
    return _append_history(session, job_id, attempt, history, allowed_from, {})


def record_progress(
    session: Session, job_id: str, attempt: int, progress: dict[str, Any], lease_s: float = 30.0
) -> bool:
    """Store the live progress of a running attempt (its phase), renewing its lease; False if
    the attempt no longer owns the job."""
    now = utcnow()
    stmt = (
        update(Job)
        .where(Job.id == job_id, Job.status == JobStatus.RUNNING.value, Job.attempts == attempt)
        .values(
            progress=progress, updated_at=now, lease_expires_at=now + timedelta(seconds=lease_s)
        )
        .execution_options(**_NO_SYNC)
    )
    return _rowcount(session.execute(stmt)) == 1


def renew_lease(session: Session, job_id: str, attempt: int, lease_s: float) -> bool:
    """Heartbeat: push the running attempt's lease ``lease_s`` ahead; False if not ours."""
    stmt = (
        update(Job)
        .where(Job.id == job_id, Job.status == JobStatus.RUNNING.value, Job.attempts == attempt)
        .values(lease_expires_at=utcnow() + timedelta(seconds=lease_s))
        .execution_options(**_NO_SYNC)
    )
    return _rowcount(session.execute(stmt)) == 1


@dataclass(frozen=True)
class LapsedJob:
    """A running job whose lease lapsed: its worker stopped renewing it."""

    id: str
    attempts: int
    started_at: datetime | None
    problem: dict[str, Any]
    cancel_requested: bool
    lease_expires_at: datetime | None = None

    def running_s(self, lease_s: float) -> float:
        """Seconds the attempt ran: from its start to its last renewal (the lapsed lease less
        its length), not the time it took to notice the worker was gone."""
        if self.started_at is None or self.lease_expires_at is None:
            return 0.0
        last_alive = self.lease_expires_at - timedelta(seconds=lease_s)
        return max(0.0, (last_alive - self.started_at).total_seconds())


def lapsed_running_jobs(session: Session, now: datetime, limit: int = 100) -> list[LapsedJob]:
    """Running jobs whose lease expired before ``now``, oldest lease first."""
    rows = session.execute(
        select(
            Job.id,
            Job.attempts,
            Job.started_at,
            Job.problem,
            Job.cancel_requested,
            Job.lease_expires_at,
        )
        .where(Job.status == JobStatus.RUNNING.value, Job.lease_expires_at < now)
        .order_by(Job.lease_expires_at)
        .limit(limit)
    ).all()
    return [LapsedJob(r[0], int(r[1]), r[2], r[3], bool(r[4]), r[5]) for r in rows]


def requeue_lapsed(session: Session, job_id: str, attempt: int, now: datetime) -> bool:
    """Put a running job with a lapsed lease back to ``queued`` (only if nothing changed)."""
    stmt = (
        update(Job)
        .where(
            Job.id == job_id,
            Job.status == JobStatus.RUNNING.value,
            Job.attempts == attempt,
            Job.lease_expires_at < now,
        )
        .values(
            status=JobStatus.QUEUED.value,
            lease_expires_at=None,
            lease_holder=None,
            dispatch_due_at=now,
            updated_at=now,
        )
        .execution_options(**_NO_SYNC)
    )
    return _rowcount(session.execute(stmt)) == 1


def finish_lapsed(
    session: Session, job_id: str, attempt: int, now: datetime, to: str, code: str, message: str
) -> bool:
    """End a running job with a lapsed lease as ``to`` (history kept), if nothing changed."""
    stmt = (
        update(Job)
        .where(
            Job.id == job_id,
            Job.status == JobStatus.RUNNING.value,
            Job.attempts == attempt,
            Job.lease_expires_at < now,
        )
        .values(
            status=to,
            lease_expires_at=None,
            updated_at=now,
            finished_at=now,
            error_code=code,
            error_message=message,
        )
        .execution_options(**_NO_SYNC)
    )
    return _rowcount(session.execute(stmt)) == 1


def claim_stale_queued(
    session: Session, now: datetime, older_than_s: float, limit: int = 100
) -> list[str]:
    """Queued jobs untouched for ``older_than_s``, made due to be sent again (their queue
    message may have been lost with a broker); ``updated_at`` is bumped so only one sweeper
    takes each. A job a live local pool holds (its hold renewed) waits there its turn."""
    cutoff = now - timedelta(seconds=older_than_s)
    unheld = or_(Job.lease_holder.is_(None), Job.lease_expires_at < now)
    ids = list(
        session.execute(
            select(Job.id)
            .where(Job.status == JobStatus.QUEUED.value, Job.updated_at < cutoff, unheld)
            .order_by(Job.updated_at)
            .limit(limit)
        ).scalars()
    )
    claimed: list[str] = []
    for job_id in ids:
        stmt = (
            update(Job)
            .where(Job.id == job_id, Job.status == JobStatus.QUEUED.value, Job.updated_at < cutoff)
            .values(updated_at=now, dispatch_due_at=now)
            .execution_options(**_NO_SYNC)
        )
        if _rowcount(session.execute(stmt)) == 1:
            claimed.append(job_id)
    return claimed


def release_dead_holders(
    session: Session, is_dead: Callable[[str], bool], *, requeue: bool = True
) -> list[str]:
    """Free the running jobs whose lease holder ``is_dead``; returns their ids.

    With ``requeue`` they go back to ``queued`` (for the caller to dispatch); without, their
    lease is made to lapse now, so whichever sweeper runs next (this server's after a restart,
    or another server's at once) re-queues and sends them. Only a holder known to be gone is
    touched (a process of this host that no longer exists), never a live attempt of another
    server or worker: those keep their job until their lease lapses. Each change is fenced by
    the attempt and the holder.
    """
    now = utcnow()
    freed: dict[str, Any] = (
        {"status": JobStatus.QUEUED.value, "lease_expires_at": None, "lease_holder": None}
        if requeue
        else {"lease_expires_at": now - timedelta(seconds=1)}
    )
    rows = session.execute(
        select(Job.id, Job.attempts, Job.lease_holder).where(
            Job.status == JobStatus.RUNNING.value, Job.lease_holder.is_not(None)
        )
    ).all()
    released = []
    for job_id, attempts, holder in rows:
        if holder is None or not is_dead(holder):
            continue
        stmt = (
            update(Job)
            .where(
                Job.id == job_id,
                Job.status == JobStatus.RUNNING.value,
                Job.attempts == attempts,
                Job.lease_holder == holder,
            )
            .values(**freed, updated_at=now)
            .execution_options(**_NO_SYNC)
        )
        if _rowcount(session.execute(stmt)) == 1:
            released.append(job_id)
    return released


def count_active(session: Session, owner: str) -> int:
    """Number of the owner's queued and running jobs."""
    stmt = (
        select(func.count())
        .select_from(Job)
        .where(Job.owner == owner, Job.status.in_(list(ACTIVE_STATUSES)))
    )
    return int(session.execute(stmt).scalar_one())


def dispatch_rank(session: Session, job_id: str) -> int:
    """How many of the job's client's jobs, queued or running, are older than it (0 if none or
    if the job is gone): its fair-share rank."""
    job = session.execute(select(Job.owner, Job.created_at).where(Job.id == job_id)).one_or_none()
    if job is None:
        return 0
    owner, created_at = job
    ahead = session.execute(
        select(func.count())
        .select_from(Job)
        .where(
            Job.owner == owner,
            Job.status.in_(list(ACTIVE_STATUSES)),
            or_(Job.created_at < created_at, and_(Job.created_at == created_at, Job.id < job_id)),
        )
    ).scalar_one()
    return int(ahead)


def mark_dispatched(session: Session, job_id: str, now: datetime | None = None) -> bool:
    """Record that a queued job's message was handed to the queue (its outbox entry is done);
    ``updated_at`` becomes the send's mark (see :func:`resend_lost`)."""
    stmt = (
        update(Job)
        .where(Job.id == job_id, Job.status == JobStatus.QUEUED.value)
        .values(dispatch_due_at=None, updated_at=now or utcnow())
        .execution_options(**_NO_SYNC)
    )
    return _rowcount(session.execute(stmt)) == 1


def sent_queued_jobs(session: Session, limit: int = 1000) -> list[tuple[str, datetime]]:
    """Queued jobs marked sent to the broker (not due, held by no local pool), oldest send
    first, each with its send's mark (``updated_at``)."""
    rows = session.execute(
        select(Job.id, Job.updated_at)
        .where(
            Job.status == JobStatus.QUEUED.value,
            Job.dispatch_due_at.is_(None),
            Job.lease_holder.is_(None),
        )
        .order_by(Job.updated_at)
        .limit(limit)
    ).all()
    return [(str(job_id), mark) for job_id, mark in rows]


def resend_lost(session: Session, job_id: str, mark: datetime, now: datetime) -> bool:
    """Make a sent queued job due again (its message is lost), only if it is still queued
    and unchanged since the send marked ``mark``; True if it was."""
    stmt = (
        update(Job)
        .where(
            Job.id == job_id,
            Job.status == JobStatus.QUEUED.value,
            Job.dispatch_due_at.is_(None),
            Job.lease_holder.is_(None),
            Job.updated_at == mark,
        )
        .values(dispatch_due_at=now, updated_at=now)
        .execution_options(**_NO_SYNC)
    )
    return _rowcount(session.execute(stmt)) == 1


def hold_queued(
    session: Session,
    job_id: str,
    holder: str,
    hold_s: float,
    progress: dict[str, Any] | None = None,
) -> bool:
    """Record that the local pool of the server ``holder`` (``host/pid``) holds a queued job,
    for ``hold_s`` unless renewed (:func:`renew_holds`); with ``progress`` as its note."""
    now = utcnow()
    values: dict[str, Any] = {
        "lease_holder": holder,
        "lease_expires_at": now + timedelta(seconds=hold_s),
    }
    if progress is not None:
        values.update(progress=progress, updated_at=now)
    stmt = (
        update(Job)
        .where(Job.id == job_id, Job.status == JobStatus.QUEUED.value)
        .values(**values)
        .execution_options(**_NO_SYNC)
    )
    return _rowcount(session.execute(stmt)) == 1


def renew_holds(session: Session, holder: str, hold_s: float) -> int:
    """Push ahead the holds of every queued job ``holder``'s pool holds; how many."""
    stmt = (
        update(Job)
        .where(Job.status == JobStatus.QUEUED.value, Job.lease_holder == holder)
        .values(lease_expires_at=utcnow() + timedelta(seconds=hold_s))
        .execution_options(**_NO_SYNC)
    )
    return _rowcount(session.execute(stmt))


def release_holds(
    session: Session,
    now: datetime,
    is_gone: Callable[[str], bool],
    *,
    lapsed: bool = True,
) -> list[str]:
    """Free the queued jobs held by a pool whose server ``is_gone`` (or, with ``lapsed``,
    whose hold was not renewed in time) and make them due now, for the relay of any server to
    send; returns their ids. Each change is fenced by the holder and the hold seen."""
    rows = session.execute(
        select(Job.id, Job.lease_holder, Job.lease_expires_at).where(
            Job.status == JobStatus.QUEUED.value, Job.lease_holder.is_not(None)
        )
    ).all()
    released: list[str] = []
    for job_id, holder, until in rows:
        expired = lapsed and (until is None or until < now)
        if not (expired or is_gone(str(holder))):
            continue
        held = Job.lease_expires_at.is_(None) if until is None else Job.lease_expires_at == until
        stmt = (
            update(Job)
            .where(
                Job.id == job_id,
                Job.status == JobStatus.QUEUED.value,
                Job.lease_holder == holder,
                held,
            )
            .values(lease_holder=None, lease_expires_at=None, dispatch_due_at=now, updated_at=now)
            .execution_options(**_NO_SYNC)
        )
        if _rowcount(session.execute(stmt)) == 1:
            released.append(str(job_id))
    return released


def take_queued(
    session: Session, holder: str, hold_s: float, is_gone: Callable[[str], bool]
) -> list[str]:
    """Queued jobs free for ``holder``'s pool, oldest first, each now held by it: those held by
    no pool, by this one, or by a pool whose server is gone or whose hold lapsed (never one a
    live server holds). Their outbox entries are closed: the pool is their queue."""
    now = utcnow()
    rows = session.execute(
        select(Job.id, Job.lease_holder, Job.lease_expires_at)
        .where(Job.status == JobStatus.QUEUED.value)
        .order_by(Job.created_at, Job.id)
    ).all()
    taken: list[str] = []
    for job_id, held_by, until in rows:
        held_elsewhere = held_by is not None and held_by != holder
        if held_elsewhere and until is not None and until >= now and not is_gone(str(held_by)):
            continue  # another live server's pool holds it
        same = Job.lease_holder.is_(None) if held_by is None else Job.lease_holder == held_by
        stmt = (
            update(Job)
            .where(Job.id == job_id, Job.status == JobStatus.QUEUED.value, same)
            .values(
                lease_holder=holder,
                lease_expires_at=now + timedelta(seconds=hold_s),
                dispatch_due_at=None,
                updated_at=now,
            )
            .execution_options(**_NO_SYNC)
        )
        if _rowcount(session.execute(stmt)) == 1:
            taken.append(str(job_id))
    return taken


def claim_due_dispatches(
    session: Session, now: datetime, claim_s: float = DISPATCH_CLAIM_S, limit: int = 100
) -> list[str]:
    """Queued jobs due to be sent, oldest first, each claimed for ``claim_s`` (its due time
    moves on, so one relay sends it; if that one dies, another sends it after ``claim_s``)."""
    rows = session.execute(
        select(Job.id, Job.dispatch_due_at)
        .where(Job.status == JobStatus.QUEUED.value, Job.dispatch_due_at <= now)
        .order_by(Job.dispatch_due_at, Job.created_at)
        .limit(limit)
    ).all()
    claimed: list[str] = []
    for job_id, due in rows:
        stmt = (
            update(Job)
            .where(
                Job.id == job_id,
                Job.status == JobStatus.QUEUED.value,
                Job.dispatch_due_at == due,
            )
            .values(dispatch_due_at=now + timedelta(seconds=claim_s))
            .execution_options(**_NO_SYNC)
        )
        if _rowcount(session.execute(stmt)) == 1:
            claimed.append(job_id)
    return claimed


def withdraw_unclaimed(session: Session, job_id: str) -> bool:
    """Delete a job no worker has started (its submission failed); False if one has."""
    stmt = (
        delete(Job)
        .where(Job.id == job_id, Job.status == JobStatus.QUEUED.value, Job.attempts == 0)
        .execution_options(**_NO_SYNC)
    )
    return _rowcount(session.execute(stmt)) == 1


def add_api_key(session: Session, client: str, key_hash: str, prefix: str) -> ApiKey:
    """Store a new key's hash for ``client``."""
    key = ApiKey(
        id=str(uuid.uuid4()),
        client=client,
        key_hash=key_hash,
        prefix=prefix,
        created_at=utcnow(),
        revoked_at=None,
    )
    session.add(key)
    session.flush()
    return key


def find_api_key(session: Session, key_hash: str) -> ApiKey | None:
    """The key stored with ``key_hash``, revoked or not."""
    return session.execute(select(ApiKey).where(ApiKey.key_hash == key_hash)).scalar_one_or_none()


def list_api_keys(session: Session, client: str | None = None) -> list[ApiKey]:
    """Every key (of ``client`` if given), oldest first."""
    stmt = select(ApiKey).order_by(ApiKey.created_at, ApiKey.id)
    if client is not None:
        stmt = stmt.where(ApiKey.client == client)
    return list(session.execute(stmt).scalars())


def revoke_api_key(session: Session, key_id: str) -> bool:
    """Revoke the key ``key_id`` (id or unique id prefix); False if no active key matched."""
    matches = list(
        session.execute(
            select(ApiKey.id).where(ApiKey.id.startswith(key_id), ApiKey.revoked_at.is_(None))
        ).scalars()
    )
    if len(matches) != 1:
        return False
    stmt = (
        update(ApiKey)
        .where(ApiKey.id == matches[0], ApiKey.revoked_at.is_(None))
        .values(revoked_at=utcnow())
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
    _cancel_where(session, Job.id == job_id, owner, "cancelled on request before it started")
    session.expire_all()
    return get_job(session, job_id, owner)


def _cancel_where(session: Session, which: Any, owner: str, message: str) -> None:
    """Cancel the owner's queued jobs matching ``which`` at once (``message`` says why) and
    flag its running ones to stop at their next iteration."""
    now = utcnow()
    session.execute(
        update(Job)
        .where(which, Job.owner == owner, Job.status == JobStatus.QUEUED.value)
        .values(
            status=JobStatus.CANCELLED.value,
            cancel_requested=True,
            finished_at=now,
            updated_at=now,
            error_code="cancelled",
            error_message=message,
        )
        .execution_options(**_NO_SYNC)
    )
    session.execute(
        update(Job)
        .where(which, Job.owner == owner, Job.status == JobStatus.RUNNING.value)
        .values(cancel_requested=True, updated_at=now)
        .execution_options(**_NO_SYNC)
    )


def active_job_ids(session: Session, statuses: Iterable[str] = ACTIVE_STATUSES) -> list[str]:
    """Ids of jobs in ``statuses`` (default queued or running), oldest first (for re-dispatch
    after a restart)."""
    stmt = select(Job.id).where(Job.status.in_(list(statuses))).order_by(Job.created_at, Job.id)
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


# --- batches ------------------------------------------------------------------------------


@dataclass(frozen=True)
class NewBatch:
    """What the API stores when a batch is submitted (its children are :class:`NewJob`)."""

    owner: str
    kind: str
    request: dict[str, Any]
    size: int
    name: str | None = None
    idempotency_key: str | None = None
    request_hash: str | None = None


def create_batch(
    session: Session, new: NewBatch, children: Sequence[NewJob]
) -> tuple[Batch, list[Job]]:
    """Insert the batch and its children (queued, in order, each its own outbox entry)."""
    batch = Batch(
        id=str(uuid.uuid4()),
        owner=new.owner,
        name=new.name,
        kind=new.kind,
        request=new.request,
        size=new.size,
        idempotency_key=new.idempotency_key,
        request_hash=new.request_hash,
        cancel_requested=False,
        created_at=utcnow(),
    )
    session.add(batch)
    session.flush()
    jobs = [
        create_job(
            session,
            NewJob(
                owner=child.owner,
                method=child.method,
                problem=child.problem,
                scenario=child.scenario,
                batch_id=batch.id,
                batch_index=index,
                batch_parameters=child.batch_parameters,
                warnings=child.warnings,
                overrides=child.overrides,
            ),
        )
        for index, child in enumerate(children)
    ]
    return batch, jobs


def get_batch(session: Session, batch_id: str, owner: str) -> Batch | None:
    """The batch ``batch_id`` of ``owner``."""
    stmt = select(Batch).where(Batch.id == batch_id, Batch.owner == owner)
    return session.execute(stmt).scalar_one_or_none()


def find_batch_by_idempotency_key(session: Session, owner: str, key: str) -> Batch | None:
    """The owner's batch submitted with Idempotency-Key ``key``."""
    stmt = select(Batch).where(Batch.owner == owner, Batch.idempotency_key == key)
    return session.execute(stmt).scalar_one_or_none()


def list_batches(session: Session, owner: str, limit: int, offset: int) -> tuple[list[Batch], int]:
    """A page of the owner's batches, newest first, and how many there are."""
    total = session.execute(
        select(func.count()).select_from(Batch).where(Batch.owner == owner)
    ).scalar_one()
    rows = session.execute(
        select(Batch)
        .where(Batch.owner == owner)
        .order_by(Batch.created_at.desc(), Batch.id)
        .limit(limit)
        .offset(offset)
    ).scalars()
    return list(rows), int(total)


def batch_counts(session: Session, batch_ids: Sequence[str]) -> dict[str, dict[str, int]]:
    """For each batch, how many of its children are in each status."""
    counts: dict[str, dict[str, int]] = {batch_id: {} for batch_id in batch_ids}
    if not batch_ids:
        return counts
    rows = session.execute(
        select(Job.batch_id, Job.status, func.count())
        .where(Job.batch_id.in_(list(batch_ids)))
        .group_by(Job.batch_id, Job.status)
    )
    for batch_id, status, count in rows:
        counts[str(batch_id)][str(status)] = int(count)
    return counts


@dataclass(frozen=True)
class BatchChild:
    """One child of a batch as its summary reads it."""

    id: str
    index: int
    parameters: dict[str, Any]
    status: str
    error_code: str | None
    result: dict[str, Any] | None


SUMMARY_PARTS: tuple[tuple[str, ...], ...] = (
    ("objective",),
    ("timing",),
    ("failure",),
    ("verification", "feasible"),
    ("verification", "final_state"),
    ("verification", "path_maxima"),
    ("verification", "no_fly_zones"),
)
"""The parts of a child's result document a batch summary reads (not its trajectory, history
or propagated flight, which make most of its size)."""

TRACK_PARTS: tuple[tuple[str, ...], ...] = (
    ("verification", "propagated", "longitude_deg"),
    ("verification", "propagated", "latitude_deg"),
)
"""The parts of a child's result a footprint's plot reads: its flown ground track."""


def batch_children(
    session: Session,
    batch_id: str,
    owner: str,
    parts: Sequence[tuple[str, ...]] = SUMMARY_PARTS,
    chunk: int = 50,
) -> Iterator[BatchChild]:
    """The batch's children in order, each with the ``parts`` of its result document (a
    document of those parts only; None without a result), read ``chunk`` at a time (one query
    each: the reader's autocommit session has no server-side cursor)."""
    start = 0
    while True:
        stmt = (
            select(
                Job.id,
                Job.batch_index,
                Job.batch_parameters,
                Job.status,
                Job.error_code,
                Job.result.is_(None),
                *(Job.result[path] for path in parts),
            )
            .where(
                Job.batch_id == batch_id,
                Job.owner == owner,
                Job.batch_index >= start,
                Job.batch_index < start + chunk,
            )
            .order_by(Job.batch_index)
        )
        rows = session.execute(stmt).all()
        if not rows:
            return
        for row in rows:
            yield BatchChild(
                id=row[0],
                index=int(row[1] or 0),
                parameters=dict(row[2] or {}),
                status=row[3],
                error_code=row[4],
                result=None if row[5] else _nested(zip(parts, row[6:], strict=True)),
            )
        start += chunk


def batch_children_state(session: Session, batch_id: str, owner: str) -> list[tuple[Any, ...]]:
    """Each child's status in order, with when it last changed once finished (an active child's
    progress changes nothing a summary shows): what a batch's plot depends on."""
    stmt = (
        select(Job.status, Job.updated_at)
        .where(Job.batch_id == batch_id, Job.owner == owner)
        .order_by(Job.batch_index)
    )
    return [
        (status, None if status in ACTIVE_STATUSES else updated_at)
        for status, updated_at in session.execute(stmt)
    ]


def _nested(parts: Iterable[tuple[tuple[str, ...], Any]]) -> dict[str, Any]:
    """A document holding each value at its path (absent values left out)."""
    document: dict[str, Any] = {}
    for path, value in parts:
        if value is None:
            continue
        node = document
        for key in path[:-1]:
            node = node.setdefault(key, {})
        node[path[-1]] = value
    return document


def chained_batch(session: Session, batch_id: str) -> bool:
    """Whether the batch chains its children (each starts from its nearest finished sibling)."""
    found = session.execute(
        select(Batch.request["chain"].as_boolean()).where(Batch.id == batch_id)
    ).scalar_one_or_none()
    return bool(found)


def finished_siblings(session: Session, batch_id: str) -> list[tuple[str, dict[str, Any]]]:
    """(id, parameters) of the batch's children that succeeded so far."""
    rows = session.execute(
        select(Job.id, Job.batch_parameters).where(
            Job.batch_id == batch_id, Job.status == JobStatus.SUCCEEDED.value
        )
    )
    return [(str(job_id), dict(parameters or {})) for job_id, parameters in rows]


def job_trajectory(session: Session, job_id: str) -> dict[str, Any] | None:
    """The trajectory of a job's result document (None without one)."""
    result = session.execute(select(Job.result).where(Job.id == job_id)).scalar_one_or_none()
    trajectory = (result or {}).get("trajectory")
    return trajectory if isinstance(trajectory, dict) else None


def cancel_batch(session: Session, batch_id: str, owner: str) -> Batch | None:
    """Flag the batch cancelled, cancel its queued children at once and ask its running ones to
    stop (as :func:`request_cancel` does for one job); the batch, or None if not the owner's."""
    batch = get_batch(session, batch_id, owner)
    if batch is None:
        return None
    batch.cancel_requested = True
    _cancel_where(
        session, Job.batch_id == batch_id, owner, "cancelled with its batch before it started"
    )
    session.flush()
    return batch
