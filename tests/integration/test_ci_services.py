"""The test command's service step (``.ci/services``, sourced by ``.ci/run``): it starts a
stopped Redis, and it stops with one line naming what is missing instead of letting the tests
skip. Run as real bash processes against real ports."""

from __future__ import annotations

import contextlib
import subprocess
import sys
from pathlib import Path

import pytest
import redis

from tests.integration.harness import free_port, service_free_env

pytestmark = pytest.mark.slow

SCRIPT = Path(__file__).resolve().parents[2] / ".ci" / "services"


def _run(**env: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        ["bash", str(SCRIPT)],
        env=service_free_env(PYTHON=sys.executable, **env),
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def test_an_unreachable_redis_is_one_line_naming_it() -> None:
    url = f"redis://127.0.0.1:{free_port()}"
    done = _run(TEST_REDIS_URL=url, CI_NO_START="1")
    assert done.returncode == 1
    assert done.stderr.splitlines() == [f"error: Redis is not answering at {url}"]


def test_an_unreachable_postgresql_is_one_line_naming_it(redis_base_url: str) -> None:
    url = f"postgresql://postgres@127.0.0.1:{free_port()}/test"
    done = _run(TEST_REDIS_URL=redis_base_url, TEST_POSTGRES_URL=url)
    assert done.returncode == 1
    assert done.stderr.splitlines() == [f"error: PostgreSQL does not answer at {url}"]


def test_a_stopped_local_redis_is_started(pg_admin_url: str) -> None:
    """A local Redis that does not answer is started on its port, and the step then passes."""
    port = free_port()
    done = _run(TEST_REDIS_URL=f"redis://127.0.0.1:{port}", TEST_POSTGRES_URL=pg_admin_url)
    started = redis.Redis(port=port, socket_timeout=2)
    try:
        assert done.returncode == 0, done.stderr
        assert f"starting redis on port {port}" in done.stdout
        assert started.ping()
    finally:
        with contextlib.suppress(redis.ConnectionError):  # it closes the connection it came on
            started.shutdown(nosave=True)
