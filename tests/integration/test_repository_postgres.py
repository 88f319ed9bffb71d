"""The storage tests of ``tests/unit/test_service_repository.py``, on PostgreSQL (JSONB)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from app.settings import normalize_database_url
from app.storage.migrate import upgrade_database
from app.storage.session import Database, create_db_engine
from tests.integration.conftest import PgSchemas
from tests.unit.test_service_repository import *  # noqa: F403  (the same tests, other database)


@pytest.fixture  # type: ignore[no-redef]
def database(pg_schemas: PgSchemas) -> Iterator[Database]:
    engine = create_db_engine(normalize_database_url(pg_schemas.new("repo")))
    upgrade_database(engine)
    yield Database.for_engine(engine)
    engine.dispose()
