"""What a job's input says about itself: its plausibility warnings and, for a scenario job, the
overrides it was submitted with (so its result's provenance can name them).

Revision ID: 0007
Revises: 0006
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

from app.storage.models import JsonType

revision: str = "0007"
down_revision: str | None = "0006"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    """Add ``jobs.warnings`` and ``jobs.overrides`` (null for the jobs stored before)."""
    with op.batch_alter_table("jobs") as batch:
        batch.add_column(sa.Column("warnings", JsonType, nullable=True))
        batch.add_column(sa.Column("overrides", JsonType, nullable=True))


def downgrade() -> None:
    """Drop ``jobs.warnings`` and ``jobs.overrides``."""
    with op.batch_alter_table("jobs") as batch:
        batch.drop_column("overrides")
        batch.drop_column("warnings")
