"""Engines and session factories, one per database URL and process.

SQLite gets WAL and a busy timeout so the API and the local worker processes can write
concurrently; every engine is discarded in a forked child, which must open its own connections.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import Engine, create_engine, event, make_url
from sqlalchemy.exc import DBAPIError, InterfaceError, OperationalError
from sqlalchemy.exc import TimeoutError as PoolTimeoutError
from sqlalchemy.orm import Session, sessionmaker

SQLITE_BUSY_TIMEOUT_MS = 30_000


@dataclass(frozen=True)
class Database:
    """An engine with its session factory."""

    engine: Engine
    sessions: sessionmaker[Session]
    readers: sessionmaker[Session]

    @classmethod
    def for_engine(cls, engine: Engine) -> Database:
        """Session factories over ``engine``: transactional, and autocommit for reads."""
        autocommit = engine.execution_options(isolation_level="AUTOCOMMIT")
        return cls(
            engine,
            sessionmaker(engine, expire_on_commit=False),
            sessionmaker(autocommit, expire_on_commit=False),
        )

    @contextmanager
    def session(self) -> Iterator[Session]:
        """A session committed on success and rolled back on error."""
        with self.sessions() as session:
            try:
                yield session
                session.commit()
            except BaseException:
                session.rollback()
                raise

    @contextmanager
    def reader(self) -> Iterator[Session]:
        """A session for reads only, in autocommit mode (no BEGIN/COMMIT round trips)."""
        with self.readers() as session:
            yield session

    autocommit = reader
    """The same autocommit session for writes that are each one conditional statement (a claim,
    a fenced update): every statement is its own transaction, no BEGIN/COMMIT round trips."""


def _configure_sqlite(engine: Engine) -> None:
    @event.listens_for(engine, "connect")
    def _pragmas(dbapi_connection: Any, _record: Any) -> None:
        cursor = dbapi_connection.cursor()
        cursor.execute("PRAGMA journal_mode=WAL")
        cursor.execute("PRAGMA synchronous=NORMAL")
        cursor.execute(f"PRAGMA busy_timeout={SQLITE_BUSY_TIMEOUT_MS}")
        cursor.close()


def create_db_engine(url: str) -> Engine:
    """A new engine for ``url``; creates the parent folder of a SQLite file."""
    parsed = make_url(url)
    if parsed.get_backend_name() == "sqlite":
        database = parsed.database
        if database and database != ":memory:" and not database.startswith("file:"):
            Path(database).parent.mkdir(parents=True, exist_ok=True)
        engine = create_engine(
            url, connect_args={"timeout": SQLITE_BUSY_TIMEOUT_MS / 1000}, pool_pre_ping=True
        )
        _configure_sqlite(engine)
        return engine
    return create_engine(url, pool_pre_ping=True, pool_size=5, max_overflow=10)


_lock = threading.Lock()
_databases: dict[str, Database] = {}


def get_database(url: str) -> Database:
    """The process-wide :class:`Database` for ``url`` (created on first use)."""
    with _lock:
        database = _databases.get(url)
        if database is None:
            database = Database.for_engine(create_db_engine(url))
            _databases[url] = database
        return database


def dispose_all() -> None:
    """Close every cached engine's connections and forget the engines."""
    with _lock:
        for database in _databases.values():
            database.engine.dispose()
        _databases.clear()


def _forget_after_fork() -> None:
    # The child must not reuse the parent's sockets; close=False leaves them to the parent.
    for database in _databases.values():
        database.engine.dispose(close=False)
    _databases.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_after_fork)


def database_unreachable(exc: BaseException) -> bool:
    """Whether ``exc`` says the database cannot be reached (down, restarting, pool exhausted),
    so that the same statement may succeed later, rather than that it refused the statement."""
    if isinstance(exc, OperationalError | InterfaceError | PoolTimeoutError):
        return True
    return isinstance(exc, DBAPIError) and bool(exc.connection_invalidated)
