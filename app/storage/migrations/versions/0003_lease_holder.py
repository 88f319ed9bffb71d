"""Record which process holds a running attempt's lease.

Revision ID: 0003
Revises: 0002
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0003"
down_revision: str | None = "0002"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    """Add ``jobs.lease_holder`` (``host/pid`` of the process running the attempt)."""
    with op.batch_alter_table("jobs") as batch:
        batch.add_column(sa.Column("lease_holder", sa.String(255), nullable=True))


def downgrade() -> None:
    """Drop ``jobs.lease_holder``."""
    with op.batch_alter_table("jobs") as batch:
        batch.drop_column("lease_holder")
