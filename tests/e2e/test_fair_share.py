"""Fair shares in the embedded pool: two clients (api-keys mode on the embedded SQLite file),
one worker process; a client's single job does not wait for another client's whole backlog."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.integration.harness import (
    SCENARIO,
    ApiServer,
    ServiceClient,
    assert_fair_share,
    create_api_key,
    embedded_env,
)

pytestmark = pytest.mark.slow

SECRET = "e2e-only-3f9a1c7d5b2e8f4a6c0d1e3f5a7b9c2d"


@pytest.fixture
def clients(tmp_path: Path) -> Iterator[tuple[ServiceClient, ServiceClient]]:
    env = embedded_env(
        tmp_path,
        TRAJOPT_AUTH_MODE="api-keys",
        TRAJOPT_API_KEY_SECRET=SECRET,
    )
    keys = [create_api_key(env, name) for name in ("backlog", "single")]
    server = ApiServer(env, tmp_path / "serve.log")
    server.start_and_wait()
    pair = (ServiceClient(server.base_url, keys[0]), ServiceClient(server.base_url, keys[1]))
    try:
        yield pair
    finally:
        for client in pair:
            client.close()
        server.stop()


def test_the_embedded_pool_gives_clients_fair_shares(
    clients: tuple[ServiceClient, ServiceClient],
) -> None:
    assert_fair_share(*clients, SCENARIO)
