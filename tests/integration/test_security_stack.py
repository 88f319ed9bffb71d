"""Keys, isolation, revocation and a rate limit shared by two API processes, on real PostgreSQL,
Redis and uvicorn servers (keys made and revoked with the ``trajopt keys`` command)."""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.integration.conftest import PgSchemas
from tests.integration.harness import (
    SCENARIO,
    ApiServer,
    ServiceClient,
    create_api_key,
    forget_queue,
    run_keys_command,
)

pytestmark = pytest.mark.slow


def test_clients_are_isolated_and_a_revoked_key_is_refused_at_once(
    api: ApiServer, stack_env: dict[str, str], scenario: str
) -> None:
    key_a = create_api_key(stack_env, "team-a")
    key_b = create_api_key(stack_env, "team-b")
    a, b = ServiceClient(api.base_url, key_a), ServiceClient(api.base_url, key_b)
    try:
        job = a.submit({"scenario": scenario, "method": {"nodes": 41, "max_iterations": 3}})
        a.wait_finished(job["id"])
        own = ("", "/result", "/history", "/events", "/trajectory.csv", "/plots")
        for suffix in (*own, "/plots/convergence.png"):
            response = b.http.get(f"/v1/jobs/{job['id']}{suffix}")
            assert response.status_code == 404, (suffix, response.text)
        assert b.http.delete(f"/v1/jobs/{job['id']}").status_code == 404
        warm = {"scenario": scenario, "overrides": {"initial_guess": {"from_job": job["id"]}}}
        refused = b.http.post("/v1/jobs", json=warm)  # a warm start from another client's job
        assert refused.status_code == 404, refused.text
        assert refused.json()["error"]["field"] == "initial_guess.from_job"
        assert b.http.get("/v1/jobs").json()["total"] == 0
        assert [j["id"] for j in a.http.get("/v1/jobs").json()["items"]] == [job["id"]]
        assert ServiceClient(api.base_url).http.get("/v1/jobs").status_code == 401

        listing = run_keys_command(stack_env, "list", "--client", "team-a")
        assert listing.returncode == 0 and key_a not in listing.stdout
        key_id = listing.stdout.splitlines()[1].split()[0]
        assert run_keys_command(stack_env, "revoke", key_id).returncode == 0
        refused = a.http.get(f"/v1/jobs/{job['id']}")
        assert refused.status_code == 401
        assert refused.json()["error"]["code"] == "invalid_api_key"
        assert b.http.get("/v1/jobs").status_code == 200
    finally:
        a.close()
        b.close()


@pytest.fixture
def two_apis(
    stack_env: dict[str, str], pg_schemas: PgSchemas, tmp_path: Path
) -> Iterator[tuple[ApiServer, ApiServer]]:
    env = dict(stack_env)
    env.update(
        DATABASE_URL=pg_schemas.new("rate"),
        TRAJOPT_QUEUE_NAME=f"trajopt-rate-{uuid.uuid4().hex[:10]}",
        TRAJOPT_RATE_READ_PER_WINDOW="5",
        TRAJOPT_RATE_SUBMIT_PER_WINDOW="1",
        TRAJOPT_RATE_WINDOW_S="3600",
        TRAJOPT_RATE_AUTH_FAILURES_PER_WINDOW="4",
    )
    key = create_api_key(env, "rate")
    first = ApiServer(env, tmp_path / "api-1.log", key)
    second = ApiServer(env, tmp_path / "api-2.log", key)
    first.start_and_wait()
    second.start_and_wait()
    try:
        yield first, second
    finally:
        first.stop()
        second.stop()
        forget_queue(env["REDIS_URL"], env["TRAJOPT_QUEUE_NAME"])


def test_the_rate_limit_is_shared_by_api_processes(two_apis: tuple[ApiServer, ApiServer]) -> None:
    one, two = (server.client() for server in two_apis)
    try:
        codes = [c.http.get("/v1/jobs").status_code for c in (one, two, one, two, one)]
        assert codes == [200] * 5
        for c in (one, two):  # the sixth read is refused by either process
            refused = c.http.get("/v1/jobs")
            assert refused.status_code == 429
            assert 1 <= int(refused.headers["retry-after"]) <= 3600
        body = {"scenario": SCENARIO, "method": {"nodes": 41, "max_iterations": 2}}
        assert one.http.post("/v1/jobs", json=body).status_code == 202
        assert two.http.post("/v1/jobs", json=body).status_code == 429
    finally:
        one.close()
        two.close()


def test_failed_authentications_are_limited_per_address_before_any_lookup(
    two_apis: tuple[ApiServer, ApiServer],
) -> None:
    """Four 401s from one address, spread over two API processes, use up its window: the next
    request from it is a 429 with Retry-After, a valid key included (the address is refused
    before any key is looked up)."""
    wrong = [ServiceClient(server.base_url, "tj_" + "x" * 43) for server in two_apis]
    keyless = ServiceClient(two_apis[0].base_url)
    valid = two_apis[1].client()
    try:
        assert valid.http.get("/v1/jobs").status_code == 200  # a success counts nothing
        codes = [c.http.get("/v1/jobs").status_code for c in (*wrong, keyless, wrong[0])]
        assert codes == [401] * 4
        for c in (wrong[1], keyless, valid):
            refused = c.http.get("/v1/jobs")
            assert refused.status_code == 429, refused.text
            assert refused.json()["error"]["code"] == "rate_limited"
            assert "failed authentications" in refused.json()["error"]["message"]
            assert 1 <= int(refused.headers["retry-after"]) <= 3600
    finally:
        for c in (*wrong, keyless, valid):
            c.close()


def test_the_python_client_sends_its_api_key(
    api: ApiServer, stack_env: dict[str, str], scenario: str
) -> None:
    from app.client import AuthenticationError, TrajoptClient

    key = create_api_key(stack_env, "client-lib")
    with TrajoptClient(api.base_url, key) as client:
        job = client.submit_scenario(scenario, method={"nodes": 41, "max_iterations": 2})
        assert client.wait(job["id"], timeout_s=120)["status"] in ("failed", "succeeded")
        assert [j["id"] for j in client.jobs()] == [job["id"]]
    with TrajoptClient(api.base_url) as keyless, pytest.raises(AuthenticationError) as refused:
        keyless.job(job["id"])
    assert refused.value.code == "missing_api_key"
