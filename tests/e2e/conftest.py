"""A ``trajopt serve`` on its embedded defaults (SQLite, local pool) shared by the e2e tests."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.integration.harness import ApiServer, ServiceClient, embedded_env


@pytest.fixture(scope="session")
def embedded_data_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The data folder (SQLite file) of :func:`embedded_server`."""
    return tmp_path_factory.mktemp("embedded-contract")


@pytest.fixture(scope="session")
def embedded_server(embedded_data_dir: Path) -> Iterator[ApiServer]:
    """One embedded server for the session's contract, docs and override tests."""
    env = embedded_env(embedded_data_dir)
    yield from ApiServer(env, embedded_data_dir / "serve.log").serving()


@pytest.fixture
def embedded_client(embedded_server: ApiServer) -> Iterator[ServiceClient]:
    """An HTTP client of :func:`embedded_server`."""
    yield from embedded_server.serving_client()
