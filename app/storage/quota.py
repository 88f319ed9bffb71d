"""The per-client submission lock that makes the active-job cap exact.

Counting a client's queued and running jobs and then inserting one is a race when two
submissions of the client run at once: both count 4 under a cap of 5 and both insert. Taking
the client's lock first, in the same transaction as the count and the insert, serializes the
client's submissions (other clients are not held up on PostgreSQL):

- PostgreSQL: ``pg_advisory_xact_lock`` on the client's name, released at commit or rollback;
- SQLite: ``BEGIN IMMEDIATE``, the database's write lock, taken before the count (the driver
  would otherwise begin the transaction only at the insert, after the count).
"""

from __future__ import annotations

from sqlalchemy import text
from sqlalchemy.orm import Session

from app.storage import repository

SUBMISSION_LOCK_TIMEOUT_MS = 10_000
"""How long a submission waits for its client's lock before it is refused (503, retry)."""
SUBMISSION_LOCK_SPACE = 0x7472616A  # "traj"
"""First key of the two-key advisory locks of submissions, apart from any other lock's."""


def lock_owner_submissions(session: Session, owner: str) -> None:
    """Hold ``owner``'s submission lock until the session's transaction ends.

    Must be the first statement of the transaction (SQLite cannot upgrade a transaction that
    has already begun to an immediate one).
    """
    dialect = session.get_bind().dialect.name
    if dialect == "postgresql":
        # a lock held by a session that never ends (a half-open connection of a killed API)
        # must not block the client forever: give up after a while (503, retry later)
        session.execute(text(f"SET LOCAL lock_timeout = '{SUBMISSION_LOCK_TIMEOUT_MS}ms'"))
        session.execute(
            text("SELECT pg_advisory_xact_lock(:space, hashtext(:owner))"),
            {"space": SUBMISSION_LOCK_SPACE, "owner": owner},
        )
    elif dialect == "sqlite":
        session.execute(text("BEGIN IMMEDIATE"))
    else:  # pragma: no cover - the service supports the two databases above
        raise NotImplementedError(f"no submission lock for the {dialect} database")


def locked_active_count(session: Session, owner: str) -> int:
    """Take ``owner``'s submission lock, then count its queued and running jobs.

    The count stays true for the rest of the transaction: no other submission of ``owner``
    can insert until it ends, and jobs only leave the active states meanwhile.
    """
    lock_owner_submissions(session, owner)
    return repository.count_active(session, owner)
