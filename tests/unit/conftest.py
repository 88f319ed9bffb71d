"""Fixtures shared by the unit tests: embedded settings in a temporary folder and its migrated
SQLite database (the real storage code, no server)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from app.settings import Settings
from app.storage.migrate import upgrade_database
from app.storage.session import Database, get_database


@pytest.fixture
def settings(tmp_path: Path) -> Settings:
    """Embedded defaults (SQLite in ``tmp_path``, no broker); modules may define their own."""
    return Settings(data_dir=tmp_path, database_url="", broker_url="")


@pytest.fixture
def database(settings: Settings) -> Iterator[Database]:
    """The migrated SQLite database of :func:`settings`."""
    database = get_database(settings.effective_database_url)
    upgrade_database(database.engine)
    yield database
