"""``trajopt keys create|list|revoke``: API-key management against the configured database."""

from __future__ import annotations

import argparse
import sys

from app.auth import create_key
from app.settings import get_settings
from app.storage import repository
from app.storage.migrate import upgrade_database
from app.storage.session import get_database


def run_keys(args: argparse.Namespace) -> int:
    """Run one ``keys`` subcommand; returns the process exit code."""
    settings = get_settings()
    database = get_database(settings.effective_database_url)
    if settings.auto_migrate:
        upgrade_database(database.engine)
    if args.keys_command == "create":
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
        with database.reader() as session:
            rows = repository.list_api_keys(session, args.client)
        print(f"{'id':36}  {'client':20}  {'prefix':10}  {'created':25}  revoked")
        for row in rows:
            revoked = row.revoked_at.isoformat(timespec="seconds") if row.revoked_at else "-"
            created = row.created_at.isoformat(timespec="seconds")
            print(f"{row.id:36}  {row.client:20}  {row.prefix:10}  {created:25}  {revoked}")
        return 0
    if args.keys_command == "revoke":
        with database.session() as session:
            done = repository.revoke_api_key(session, args.key_id)
        if not done:
            print(f"error: no single active key with id {args.key_id!r}", file=sys.stderr)
            return 1
        print(f"revoked {args.key_id}")
        return 0
    return 2
