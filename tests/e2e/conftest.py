"""A ``trajopt serve`` on its embedded defaults (SQLite, local pool) shared by the e2e tests."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.integration.harness import ApiServer, ServiceClient, service_free_env


def embedded_env(data_dir: str) -> dict[str, str]:
    """This process's environment without service settings, the data in ``data_dir``."""
    env = service_free_env()
    env.update(TRAJOPT_DATA_DIR=data_dir, TRAJOPT_LOCAL_WORKERS="1")
    return env


@pytest.fixture(scope="session")
def embedded_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ApiServer]:
    """One embedded server for the session's contract and docs tests."""
    data_dir = tmp_path_factory.mktemp("embedded-contract")
    yield from ApiServer(embedded_env(str(data_dir)), data_dir / "serve.log").serving()


@pytest.fixture
def embedded_client(embedded_server: ApiServer) -> Iterator[ServiceClient]:
    """An HTTP client of :func:`embedded_server`."""
    yield from embedded_server.serving_client()
