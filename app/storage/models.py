"""The ``jobs`` table (one row per submitted problem with status, progress, history and result),
the ``batches`` table (a study of many jobs) and the ``api_keys`` table (hashed client keys)."""

from __future__ import annotations

import os
import socket
from datetime import UTC, datetime
from enum import StrEnum
from typing import Any

from sqlalchemy import (
    JSON,
    CheckConstraint,
    DateTime,
    Float,
    Index,
    Integer,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.dialects.postgresql import JSONB
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column
from sqlalchemy.types import TypeDecorator

JsonType = JSON().with_variant(JSONB(), "postgresql")


class JobStatus(StrEnum):
    """Lifecycle of a job; the last four are terminal and never change again."""

    QUEUED = "queued"
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    CANCELLED = "cancelled"
    TIMED_OUT = "timed_out"


TERMINAL_STATUSES: frozenset[str] = frozenset(
    {JobStatus.SUCCEEDED, JobStatus.FAILED, JobStatus.CANCELLED, JobStatus.TIMED_OUT}
)
ACTIVE_STATUSES: frozenset[str] = frozenset({JobStatus.QUEUED, JobStatus.RUNNING})
ALL_STATUSES: tuple[str, ...] = tuple(s.value for s in JobStatus)


class UtcDateTime(TypeDecorator[datetime]):
    """Timezone-aware UTC timestamps on every backend (SQLite drops the offset otherwise)."""

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Any) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError("naive datetime given to a UTC column")
        return value.astimezone(UTC)

    def process_result_value(self, value: datetime | None, dialect: Any) -> datetime | None:
        if value is None:
            return None
        return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


def process_identity(pid: int | None = None) -> str:
    """``host/pid`` naming a process: the holder recorded on the lease of the attempt it runs."""
    return f"{socket.gethostname()}/{os.getpid() if pid is None else pid}"


def utcnow() -> datetime:
    """The current time in UTC, aware."""
    return datetime.now(UTC)


class Base(DeclarativeBase):
    """Declarative base of the service's tables."""


class Job(Base):
    """A submitted problem and everything the service knows about its solve."""

    __tablename__ = "jobs"
    __table_args__ = (
        UniqueConstraint("owner", "idempotency_key", name="uq_jobs_owner_idempotency_key"),
        CheckConstraint(
            "status IN ('queued','running','succeeded','failed','cancelled','timed_out')",
            name="ck_jobs_status",
        ),
        Index("ix_jobs_owner_created", "owner", "created_at"),
        Index("ix_jobs_status", "status"),
        Index("ix_jobs_status_lease", "status", "lease_expires_at"),
        Index("ix_jobs_status_dispatch_due", "status", "dispatch_due_at"),
        Index("ix_jobs_batch", "batch_id", "batch_index"),
    )

    id: Mapped[str] = mapped_column(String(36), primary_key=True)
    owner: Mapped[str] = mapped_column(String(128), nullable=False)
    status: Mapped[str] = mapped_column(String(16), nullable=False, default=JobStatus.QUEUED)
    method: Mapped[str] = mapped_column(String(64), nullable=False)
    scenario: Mapped[str | None] = mapped_column(String(128), nullable=True)
    problem: Mapped[dict[str, Any]] = mapped_column(JsonType, nullable=False)
    idempotency_key: Mapped[str | None] = mapped_column(String(255), nullable=True)
    request_hash: Mapped[str | None] = mapped_column(String(64), nullable=True)
    attempts: Mapped[int] = mapped_column(Integer, nullable=False, default=0)
    cancel_requested: Mapped[bool] = mapped_column(nullable=False, default=False)
    created_at: Mapped[datetime] = mapped_column(UtcDateTime, nullable=False, default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(UtcDateTime, nullable=False, default=utcnow)
    started_at: Mapped[datetime | None] = mapped_column(UtcDateTime, nullable=True)
    finished_at: Mapped[datetime | None] = mapped_column(UtcDateTime, nullable=True)
    error_code: Mapped[str | None] = mapped_column(String(64), nullable=True)
    error_message: Mapped[str | None] = mapped_column(Text, nullable=True)
    progress: Mapped[dict[str, Any] | None] = mapped_column(JsonType, nullable=True)
    history: Mapped[list[dict[str, Any]]] = mapped_column(JsonType, nullable=False, default=list)
    result: Mapped[dict[str, Any] | None] = mapped_column(JsonType, nullable=True)
    solve_s: Mapped[float | None] = mapped_column(Float, nullable=True)
    lease_expires_at: Mapped[datetime | None] = mapped_column(UtcDateTime, nullable=True)
    """Heartbeat of the running attempt: past this instant its worker is presumed gone."""
    lease_holder: Mapped[str | None] = mapped_column(String(255), nullable=True)
    """``host/pid`` of the process running the attempt (see :func:`process_identity`)."""
    dispatch_due_at: Mapped[datetime | None] = mapped_column(UtcDateTime, nullable=True)
    """Outbox: when this queued job is due to be sent to a worker (again); null once sent."""
    batch_id: Mapped[str | None] = mapped_column(String(36), nullable=True)
    """The batch this job is a child of (null for a job submitted alone)."""
    batch_index: Mapped[int | None] = mapped_column(Integer, nullable=True)
    """Position of the child in its batch (0-based)."""
    batch_parameters: Mapped[dict[str, Any] | None] = mapped_column(JsonType, nullable=True)
    """What the batch set in this child: JSON pointer -> value."""
    warnings: Mapped[list[dict[str, Any]] | None] = mapped_column(JsonType, nullable=True)
    """The problem's plausibility warnings (``app.schemas.plausibility``), found at submission."""
    overrides: Mapped[dict[str, Any] | None] = mapped_column(JsonType, nullable=True)
    """A scenario job's patches as submitted: ``{"overrides": ..., "method": ...}``."""


class Batch(Base):
    """Many jobs on one base problem (a grid, a Monte Carlo dispersion, a method comparison);
    its status and summary are read from its children."""

    __tablename__ = "batches"
    __table_args__ = (
        UniqueConstraint("owner", "idempotency_key", name="uq_batches_owner_idempotency_key"),
        CheckConstraint(
            "kind IN ('grid','monte_carlo','methods','footprint')", name="ck_batches_kind"
        ),
        Index("ix_batches_owner_created", "owner", "created_at"),
    )

    id: Mapped[str] = mapped_column(String(36), primary_key=True)
    owner: Mapped[str] = mapped_column(String(128), nullable=False)
    name: Mapped[str | None] = mapped_column(String(200), nullable=True)
    kind: Mapped[str] = mapped_column(String(16), nullable=False)
    request: Mapped[dict[str, Any]] = mapped_column(JsonType, nullable=False)
    size: Mapped[int] = mapped_column(Integer, nullable=False)
    idempotency_key: Mapped[str | None] = mapped_column(String(255), nullable=True)
    request_hash: Mapped[str | None] = mapped_column(String(64), nullable=True)
    cancel_requested: Mapped[bool] = mapped_column(nullable=False, default=False)
    created_at: Mapped[datetime] = mapped_column(UtcDateTime, nullable=False, default=utcnow)


class ApiKey(Base):
    """A client's API key, stored only as a keyed hash; revoked keys stay for the record."""

    __tablename__ = "api_keys"

    id: Mapped[str] = mapped_column(String(36), primary_key=True)
    client: Mapped[str] = mapped_column(String(128), nullable=False, index=True)
    key_hash: Mapped[str] = mapped_column(String(64), nullable=False, unique=True)
    prefix: Mapped[str] = mapped_column(String(16), nullable=False)
    created_at: Mapped[datetime] = mapped_column(UtcDateTime, nullable=False, default=utcnow)
    revoked_at: Mapped[datetime | None] = mapped_column(UtcDateTime, nullable=True)
