"""``trajopt keys create|list|revoke``: API-key management against the configured database.

``create`` needs api-keys mode (the secret the key is hashed with is only required there) and
refuses otherwise with exit 2. ``list`` and ``revoke`` work in either mode, since the keys stay in
the database across a mode switch; in single-user mode they add a note on stderr that the API
checks no keys until ``TRAJOPT_AUTH_MODE=api-keys``. Exit codes: 0 done, 1 no single active key
matched the id to revoke, 2 invalid input or configuration (settings, database).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from sqlalchemy import make_url
from sqlalchemy.exc import ArgumentError, SQLAlchemyError

from app.auth import create_key
from app.settings import Settings, load_settings
from app.storage import repository
from app.storage.migrate import upgrade_database
from app.storage.models import ApiKey
from app.storage.session import Database, get_database

NEEDS_API_KEYS_MODE = (
    "API keys need api-keys mode: set TRAJOPT_AUTH_MODE=api-keys and TRAJOPT_API_KEY_SECRET "
    "(e.g. `openssl rand -hex 32`), the same values as for `trajopt serve`"
)
SINGLE_USER_NOTE = (
    "note: TRAJOPT_AUTH_MODE is single-user, so the API checks no keys; "
    "they take effect in api-keys mode"
)


class DatabaseUnavailableError(Exception):
    """The configured database cannot be opened or migrated; one line, password hidden."""


def safe_url(url: str) -> str:
    """``url`` with its password masked (``***``), or a placeholder if it does not parse."""
    try:
        return make_url(url).render_as_string(hide_password=True)
    except ArgumentError:
        return "(unparsable URL)"


def database_problem(exc: Exception, url: str) -> str:
    """One line for a database failure: the URL without password, and the driver's reason.

    SQLAlchemy's own text is not used whole: it carries the SQL statement and its parameters.
    """
    cause = getattr(exc, "orig", None) or exc
    if isinstance(cause, OSError) and cause.strerror:
        reason = cause.strerror + (f": {cause.filename}" if cause.filename else "")
    else:
        reason = (str(cause).strip().splitlines() or [type(cause).__name__])[0]
    return f"cannot use the database {safe_url(url)}: {reason}"


def open_database(settings: Settings) -> Database:
    """The configured database, migrated when ``auto_migrate``; ``DatabaseUnavailableError``."""
    url = settings.effective_database_url
    try:
        make_url(url)
    except ArgumentError:
        raise DatabaseUnavailableError(
            "DATABASE_URL is not a database URL (expected e.g. postgresql://user:pass@host/db)"
        ) from None
    try:
        database = get_database(url)
        if settings.auto_migrate:
            upgrade_database(database.engine)
    except (SQLAlchemyError, OSError) as exc:
        raise DatabaseUnavailableError(database_problem(exc, url)) from None
    return database


def key_table(rows: Sequence[ApiKey]) -> list[str]:
    """The keys as an aligned table (widths from the data): id, client, prefix, dates."""
    table = [("id", "client", "prefix", "created", "revoked")]
    for row in rows:
        revoked = row.revoked_at.isoformat(timespec="seconds") if row.revoked_at else "-"
        created = row.created_at.isoformat(timespec="seconds")
        table.append((row.id, row.client, row.prefix, created, revoked))
    widths = [max(len(r[i]) for r in table) for i in range(4)]
    return [
        "  ".join([*(c.ljust(w) for c, w in zip(r[:4], widths, strict=True)), r[4]]) for r in table
    ]


def _run(args: argparse.Namespace, settings: Settings) -> int:
    """Run one ``keys`` subcommand with loaded settings; the exit code."""
    single_user = settings.auth_mode != "api-keys"
    if args.keys_command == "create":
        if single_user:
            print(f"error: {NEEDS_API_KEYS_MODE}", file=sys.stderr)
            return 2
        database = open_database(settings)
        try:
            row, key = create_key(database, settings, args.client)
        except ValueError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        print(key)
        print(f"key id {row.id} for client {row.client!r}; shown once, store it now",
              file=sys.stderr)  # fmt: skip
        return 0
    if args.keys_command == "list":
        database = open_database(settings)
        with database.reader() as session:
            rows = repository.list_api_keys(session, args.client)
        for line in key_table(rows):
            print(line)
        if single_user:
            print(SINGLE_USER_NOTE, file=sys.stderr)
        return 0
    if args.keys_command == "revoke":
        key_id = args.key_id.strip()
        if not key_id:
            print("error: give the id of the key to revoke (`trajopt keys list`)", file=sys.stderr)
            return 2
        database = open_database(settings)
        with database.session() as session:
            done = repository.revoke_api_key(session, key_id)
        if not done:
            print(
                f"error: no single active key has the id or id prefix {key_id!r} "
                "(`trajopt keys list` shows them)",
                file=sys.stderr,
            )
            return 1
        print(f"revoked {key_id}")
        if single_user:
            print(SINGLE_USER_NOTE, file=sys.stderr)
        return 0
    return 2


def run_keys(args: argparse.Namespace) -> int:
    """Run one ``keys`` subcommand; returns the process exit code.

    Invalid settings raise ``ConfigurationError`` for the caller (``app.cli``) to print.
    """
    settings = load_settings()
    try:
        return _run(args, settings)
    except DatabaseUnavailableError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except SQLAlchemyError as exc:
        print(f"error: {database_problem(exc, settings.effective_database_url)}", file=sys.stderr)
        return 2
