"""The convergence history stored once: in ``jobs.history``, no longer inside the result too.

A stored result document keeps an empty ``history``, which the result route fills from
``jobs.history`` (the one store, appended per iteration). Data only; the schema is unchanged.

Revision ID: 0005
Revises: 0004
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import sqlalchemy as sa
from alembic import op

from app.storage.models import JsonType

revision: str = "0005"
down_revision: str | None = "0004"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

BATCH = 200
"""Jobs read and rewritten per round trip."""

_jobs = sa.table(
    "jobs",
    sa.column("id", sa.String(36)),
    sa.column("history", JsonType),
    sa.column("result", JsonType),
)


def _rewrite(change: Any) -> None:
    """Apply ``change(history, result) -> (history, result) | None`` to every job with a
    result document, in batches by id."""
    connection = op.get_bind()
    last = ""
    while True:
        rows = connection.execute(
            sa.select(_jobs.c.id, _jobs.c.history, _jobs.c.result)
            .where(_jobs.c.id > last, _jobs.c.result.is_not(None))
            .order_by(_jobs.c.id)
            .limit(BATCH)
        ).all()
        if not rows:
            return
        for job_id, history, result in rows:
            changed = change(history, result) if isinstance(result, dict) else None
            if changed is not None:
                connection.execute(
                    sa.update(_jobs)
                    .where(_jobs.c.id == job_id)
                    .values(history=changed[0], result=changed[1])
                )
        last = rows[-1][0]


def _strip(history: Any, result: dict[str, Any]) -> tuple[Any, dict[str, Any]] | None:
    kept = result.get("history")
    if not kept:
        return None
    return (history or kept), {**result, "history": []}


def _restore(history: Any, result: dict[str, Any]) -> tuple[Any, dict[str, Any]] | None:
    if "history" not in result or result["history"] or not history:
        return None
    return history, {**result, "history": history}


def upgrade() -> None:
    """Move each stored result's history out of the result (``jobs.history`` holds it)."""
    _rewrite(_strip)


def downgrade() -> None:
    """Put ``jobs.history`` back into each stored result document."""
    _rewrite(_restore)
