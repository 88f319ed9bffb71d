"""The jobs table as a transactional outbox: when a queued job is due to be sent to a worker.

Revision ID: 0004
Revises: 0003
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

from app.storage.models import UtcDateTime

revision: str = "0004"
down_revision: str | None = "0003"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    """Add ``jobs.dispatch_due_at`` (null once sent) with an index for the relay."""
    with op.batch_alter_table("jobs") as batch:
        batch.add_column(sa.Column("dispatch_due_at", UtcDateTime(), nullable=True))
    op.create_index("ix_jobs_status_dispatch_due", "jobs", ["status", "dispatch_due_at"])


def downgrade() -> None:
    """Drop ``jobs.dispatch_due_at``."""
    op.drop_index("ix_jobs_status_dispatch_due", table_name="jobs")
    with op.batch_alter_table("jobs") as batch:
        batch.drop_column("dispatch_due_at")
