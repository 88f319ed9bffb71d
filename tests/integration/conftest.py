"""Real services for the integration tests: PostgreSQL, Redis, a Celery worker and the API.

Each run gets its own PostgreSQL schema, Redis database number and queue name, so concurrent
runs do not collide. An unreachable service fails these tests (see ``harness.require``).
"""

from __future__ import annotations

import os
import random
import uuid
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import quote

import psycopg
import pytest
import redis

from tests.integration.harness import (
    SCENARIO,
    ApiServer,
    ServiceClient,
    ServiceProcess,
    admin_postgres_url,
    create_api_key,
    forget_queue,
    require,
    service_free_env,
)

TEST_SECRET = "it-only-5b1f0c7e9a2d4e6f8a0b2c4d6e8f0a1b"
"""Server secret of the test deployments (api-keys mode refuses a missing or default one)."""


@pytest.fixture(scope="session")
def pg_admin_url() -> str:
    """A PostgreSQL URL that can create schemas (trust auth on the loopback)."""
    return admin_postgres_url()


def with_schema(url: str, schema: str) -> str:
    """``url`` whose connections use ``schema`` first on the search path."""
    sep = "&" if "?" in url else "?"
    return f"{url}{sep}options={quote(f'-csearch_path={schema}')}"


class PgSchemas:
    """Creates throwaway schemas and drops them all at the end."""

    def __init__(self, admin_url: str) -> None:
        self.admin_url = admin_url
        self.created: list[str] = []

    def new(self, label: str) -> str:
        schema = f"trajopt_{label}_{uuid.uuid4().hex[:10]}"
        with psycopg.connect(self.admin_url, autocommit=True) as conn:
            conn.execute(f'CREATE SCHEMA "{schema}"')
        self.created.append(schema)
        return with_schema(self.admin_url, schema)

    def drop_all(self) -> None:
        with psycopg.connect(self.admin_url, autocommit=True) as conn:
            for schema in self.created:
                conn.execute(f'DROP SCHEMA IF EXISTS "{schema}" CASCADE')


@pytest.fixture(scope="session")
def pg_schemas(pg_admin_url: str) -> Iterator[PgSchemas]:
    schemas = PgSchemas(pg_admin_url)
    yield schemas
    schemas.drop_all()


@pytest.fixture(scope="session")
def redis_base_url() -> str:
    """The Redis server, without a database number."""
    url = os.environ.get("TEST_REDIS_URL", "redis://127.0.0.1:6379")
    try:
        redis.Redis.from_url(url, socket_connect_timeout=3).ping()
    except redis.RedisError as exc:
        require("Redis", str(exc))
    return url.rstrip("/")


@pytest.fixture(scope="session")
def stack_env(
    pg_schemas: PgSchemas, redis_base_url: str, tmp_path_factory: pytest.TempPathFactory
) -> dict[str, str]:
    """Environment of the API and worker processes of this run."""
    env = service_free_env()
    db_number = random.randint(1, 15)
    env.update(
        DATABASE_URL=pg_schemas.new("it"),
        REDIS_URL=f"{redis_base_url}/{db_number}",
        TRAJOPT_QUEUE_NAME=f"trajopt-it-{uuid.uuid4().hex[:10]}",
        TRAJOPT_DATA_DIR=str(tmp_path_factory.mktemp("data")),
        TRAJOPT_WORKER_MAX_TASKS_PER_CHILD="50",
        TRAJOPT_AUTH_MODE="api-keys",
        TRAJOPT_API_KEY_SECRET=TEST_SECRET,
        TRAJOPT_LEASE_S="3",
        TRAJOPT_SWEEP_INTERVAL_S="0.5",
        TRAJOPT_RATE_READ_PER_WINDOW="0",
        TRAJOPT_RATE_SUBMIT_PER_WINDOW="0",
        TRAJOPT_RATE_AUTH_FAILURES_PER_WINDOW="0",
    )
    return env


@pytest.fixture(scope="session")
def api_key(stack_env: dict[str, str]) -> str:
    """A key of client ``it`` made with the management command (which also migrates)."""
    return create_api_key(stack_env, "it")


@pytest.fixture(scope="session")
def worker(
    stack_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory
) -> Iterator[ServiceProcess]:
    """One Celery worker process (one pool child) against this run's Redis queue."""
    log = tmp_path_factory.mktemp("logs") / "worker.log"
    try:
        yield from celery_worker(stack_env, log)
    finally:
        forget_queue(stack_env["REDIS_URL"], stack_env["TRAJOPT_QUEUE_NAME"])


def celery_worker(env: dict[str, str], log: Path) -> Iterator[ServiceProcess]:
    """A Celery worker process (one pool child) on the queue of ``env``, until closed."""
    process = ServiceProcess(["-m", "app.cli", "worker", "--concurrency", "1"], env, log)
    process.start()
    try:
        process.wait_for_output(" ready.", timeout=90)
        yield process
    finally:
        process.stop()


@pytest.fixture(scope="session")
def api(
    stack_env: dict[str, str],
    worker: ServiceProcess,
    api_key: str,
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[ApiServer]:
    """The API server of this run (tests may restart it), in api-keys mode."""
    yield from ApiServer(stack_env, tmp_path_factory.mktemp("logs") / "api.log", api_key).serving()


@pytest.fixture
def client(api: ApiServer) -> Iterator[ServiceClient]:
    """An HTTP client of the running API."""
    yield from api.serving_client()


@pytest.fixture(scope="session")
def scenario() -> str:
    """The built-in scenario the tests submit (its default options solve in about 2 s)."""
    from worker.solver.scenarios import get_scenario

    return get_scenario(SCENARIO).name
