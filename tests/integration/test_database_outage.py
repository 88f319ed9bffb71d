"""A database outage seen from the API: 503 ``database_unavailable`` with Retry-After on every
route that needs the database, on a kept connection, and normal answers once it is back, from
the same API process.

The API reaches PostgreSQL through a TCP forwarder the test cuts and restores, so the machine's
shared PostgreSQL server keeps running for other tests.
"""

from __future__ import annotations

import http.client
import json
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from sqlalchemy import make_url

from bench.tcp_proxy import TcpProxy
from tests.integration.conftest import PgSchemas
from tests.integration.harness import SCENARIO, ApiServer, create_api_key, forget_queue

pytestmark = pytest.mark.slow

UNKNOWN_JOB = "3f2b8c1e-6d0a-4c55-9d1e-2a7f3b9c4e10"


@pytest.fixture
def proxy(pg_admin_url: str) -> Iterator[TcpProxy]:
    upstream = make_url(pg_admin_url)
    forwarder = TcpProxy(upstream.host or "127.0.0.1", upstream.port or 5432)
    forwarder.start()
    yield forwarder
    forwarder.cut()


@pytest.fixture
def outage_api(
    stack_env: dict[str, str], pg_schemas: PgSchemas, proxy: TcpProxy, tmp_path: Path
) -> Iterator[ApiServer]:
    """An API of its own whose database connections all go through ``proxy``."""
    env = dict(stack_env)
    direct = make_url(pg_schemas.new("dbout"))
    env["DATABASE_URL"] = direct.set(port=proxy.port).render_as_string(hide_password=False)
    env["TRAJOPT_QUEUE_NAME"] = f"trajopt-dbout-{uuid.uuid4().hex[:10]}"
    key = create_api_key(env, "dbout")
    try:
        yield from ApiServer(env, tmp_path / "api.log", key).serving()
    finally:
        forget_queue(env["REDIS_URL"], env["TRAJOPT_QUEUE_NAME"])


def _requests() -> list[tuple[str, str, bytes | None]]:
    scenario = json.dumps({"scenario": SCENARIO}).encode()
    return [
        ("GET", "/v1/jobs", None),
        ("GET", f"/v1/jobs/{UNKNOWN_JOB}", None),
        ("GET", f"/v1/jobs/{UNKNOWN_JOB}/result", None),
        ("GET", f"/v1/jobs/{UNKNOWN_JOB}/history", None),
        ("DELETE", f"/v1/jobs/{UNKNOWN_JOB}", None),
        ("POST", "/v1/jobs", scenario),
        ("POST", "/v1/problems/validate", scenario),
        ("GET", "/v1/scenarios", None),
    ]


def _call(
    connection: http.client.HTTPConnection, key: str, method: str, path: str, body: bytes | None
) -> tuple[int, dict[str, str], bytes]:
    headers = {"X-API-Key": key, "Content-Type": "application/json"}
    connection.request(method, path, body=body, headers=headers)
    response = connection.getresponse()
    return response.status, {k.lower(): v for k, v in response.getheaders()}, response.read()


def test_an_outage_is_503_with_retry_after_and_passes_without_a_restart(
    outage_api: ApiServer, proxy: TcpProxy
) -> None:
    assert outage_api.api_key is not None and outage_api.process is not None
    key, pid = outage_api.api_key, outage_api.process.pid
    connection = http.client.HTTPConnection("127.0.0.1", outage_api.port, timeout=30)
    connection.connect()
    kept = connection.sock
    assert _call(connection, key, "GET", "/v1/jobs", None)[0] == 200

    proxy.cut()
    try:
        for method, path, body in _requests():
            status, headers, payload = _call(connection, key, method, path, body)
            assert status == 503, (method, path, status, payload[:300])
            error = json.loads(payload)["error"]
            assert error["code"] == "database_unavailable", (path, error)
            assert int(headers["retry-after"]) > 0
            assert headers.get("connection") != "close"
            assert connection.sock is kept, f"{method} {path}: the connection was dropped"
        status, _, payload = _call(connection, key, "GET", "/readyz", None)
        assert status == 503 and b"database" in payload
        assert _call(connection, key, "GET", "/healthz", None)[0] == 200
    finally:
        proxy.restore()

    deadline = time.monotonic() + 20
    while True:
        status, _, payload = _call(connection, key, "GET", "/v1/jobs", None)
        if status == 200:
            break
        assert status == 503, payload[:300]  # only 503 while the pool reconnects
        assert time.monotonic() < deadline, "the API did not recover"
        time.sleep(0.2)
    body = json.dumps({"scenario": SCENARIO, "method": {"nodes": 20}}).encode()
    status, headers, payload = _call(connection, key, "POST", "/v1/jobs", body)
    assert status == 202, payload[:300]
    assert _call(connection, key, "GET", headers["location"], None)[0] == 200
    assert _call(connection, key, "GET", "/readyz", None)[0] == 200
    connection.close()
    assert outage_api.alive() and outage_api.process.pid == pid  # never restarted
    log = outage_api.log_text()
    assert "database unavailable on GET /v1/jobs" in log
    assert "Traceback" not in log.split("database unavailable", 1)[1].split("\n", 1)[0]
