"""The active-job cap and the submission rate limits hold exactly under concurrent load.

Real servers: the cap on PostgreSQL (two API processes sharing one schema, so the lock must
hold across processes) and on SQLite (an embedded server with its local pool); the moving
window on two API processes in api-keys mode sharing one Redis limiter. Windows are short
(4 s, 10 submissions: long enough for a burst on a busy machine) so the file takes seconds.
"""

from __future__ import annotations

import threading
import time
import uuid
from collections import Counter
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.e2e.conftest import embedded_env
from tests.integration.conftest import TEST_SECRET, PgSchemas
from tests.integration.harness import (
    SCENARIO,
    ApiServer,
    create_api_key,
    forget_queue,
    long_job,
)

pytestmark = pytest.mark.slow

CAP = 5
WINDOW_S = 6
PER_WINDOW = 10
REJECTED_PER_WINDOW = 5
QUICK = {"scenario": SCENARIO, "method": {"nodes": 41, "max_iterations": 2}}
INVALID = {"scenario": SCENARIO, "nodes": 20}
"""Refused with 422 (an unknown field) after the quota test, before anything is stored."""

Request = tuple[httpx.Client, dict[str, str], dict[str, Any]]
"""Who sends (a client of one server), the headers (its key), the body."""


def burst(requests: list[Request]) -> list[httpx.Response]:
    """Send every request at the same instant, one thread each; the answers in order."""
    barrier = threading.Barrier(len(requests))

    def send(request: Request) -> httpx.Response:
        http, headers, body = request
        barrier.wait()
        return http.post("/v1/jobs", json=body, headers=headers)

    with ThreadPoolExecutor(len(requests)) as pool:
        return list(pool.map(send, requests))


def clients(urls: list[str]) -> list[httpx.Client]:
    """One HTTP client per server, with room for a burst's connections."""
    limits = httpx.Limits(max_connections=100, max_keepalive_connections=100)
    return [httpx.Client(base_url=url, timeout=60.0, limits=limits) for url in urls]


def spread(https: list[httpx.Client], keys: list[str], n: int, body: Any) -> list[Request]:
    """``n`` requests of ``body`` sent round-robin to the servers and the keys."""
    return [(https[i % len(https)], {"X-API-Key": keys[i % len(keys)]}, body) for i in range(n)]


def codes(responses: list[httpx.Response]) -> Counter[tuple[int, str]]:
    """How many answers of each status and error code (``""`` for a success)."""
    return Counter(
        (r.status_code, r.json()["error"]["code"] if r.status_code >= 400 else "")
        for r in responses
    )


# --- the active-job cap -------------------------------------------------------------------


@pytest.fixture(params=["postgresql", "sqlite"])
def capped(
    request: pytest.FixtureRequest, tmp_path: Path
) -> Iterator[tuple[list[str], dict[str, str]]]:
    """API server URLs with a cap of 5 active jobs and no rate limit, and keys of the clients
    ``twenty`` and ``sixty``: two processes on PostgreSQL, or one embedded server on SQLite."""
    if request.param == "postgresql":
        pg_schemas: PgSchemas = request.getfixturevalue("pg_schemas")
        env = dict(request.getfixturevalue("stack_env"))
        env.update(
            DATABASE_URL=pg_schemas.new("cap"),
            TRAJOPT_QUEUE_NAME=f"trajopt-cap-{uuid.uuid4().hex[:10]}",
        )
        count = 2
    else:
        env = embedded_env(str(tmp_path / "data"))
        env.update(
            TRAJOPT_AUTH_MODE="api-keys",
            TRAJOPT_API_KEY_SECRET=TEST_SECRET,
            TRAJOPT_RATE_READ_PER_WINDOW="0",
            TRAJOPT_RATE_SUBMIT_PER_WINDOW="0",
        )
        count = 1
    env["TRAJOPT_MAX_ACTIVE_JOBS"] = str(CAP)
    keys = {name: create_api_key(env, name) for name in ("twenty", "sixty")}
    servers = [ApiServer(env, tmp_path / f"api-{i}.log") for i in range(count)]
    try:
        for server in servers:
            server.start_and_wait()
        yield [s.base_url for s in servers], keys
    finally:
        for server in servers:
            server.stop()
        if "TRAJOPT_QUEUE_NAME" in env:
            forget_queue(env["REDIS_URL"], env["TRAJOPT_QUEUE_NAME"])


def active_total(http: httpx.Client, key: str) -> int:
    """The client's queued and running jobs, as the API lists them."""
    response = http.get(
        "/v1/jobs", params={"status": ["queued", "running"]}, headers={"X-API-Key": key}
    )
    assert response.status_code == 200, response.text
    total: int = response.json()["total"]
    return total


def test_the_active_job_cap_is_exact_under_concurrent_submissions(
    capped: tuple[list[str], dict[str, str]],
) -> None:
    urls, keys = capped
    https = clients(urls)
    body = long_job(SCENARIO)  # the embedded pool runs one: it stays active all along
    try:
        answers = burst(spread(https, [keys["twenty"]], 20, body))
        assert codes(answers) == {(202, ""): CAP, (429, "too_many_active_jobs"): 20 - CAP}
        assert all(r.headers["retry-after"] == "10" for r in answers if r.status_code == 429)
        assert active_total(https[0], keys["twenty"]) == CAP

        # 60 at once as 30 Idempotency-Keys sent twice each: a key's two answers are the same
        # job (the second a replay, never counted against the cap) or both refused.
        requests = [
            (
                https[i % len(https)],
                {"X-API-Key": keys["sixty"], "Idempotency-Key": f"k{i // 2}"},
                body,
            )
            for i in range(60)
        ]
        answers = burst(requests)
        by_key: dict[str, set[tuple[int, str | None]]] = {}
        for (_, headers, _), answer in zip(requests, answers, strict=True):
            job_id = answer.json()["id"] if answer.status_code == 202 else None
            by_key.setdefault(headers["Idempotency-Key"], set()).add((answer.status_code, job_id))
        accepted = {key: pair for key, pair in by_key.items() if (429, None) not in pair}
        assert len(accepted) == CAP, by_key
        assert all(len(pair) == 1 for pair in by_key.values()), by_key
        assert active_total(https[0], keys["sixty"]) == CAP

        key, ((_, job_id),) = next(iter(accepted.items()))
        replay = https[-1].post(
            "/v1/jobs", json=body, headers={"X-API-Key": keys["sixty"], "Idempotency-Key": key}
        )
        assert replay.status_code == 202, replay.text
        assert (replay.json()["id"], replay.headers["idempotent-replayed"]) == (job_id, "true")
    finally:
        for http in https:
            http.close()


# --- moving windows shared by two API processes ----------------------------------------------


@pytest.fixture(scope="module")
def limited(
    stack_env: dict[str, str], pg_schemas: PgSchemas, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[tuple[list[str], dict[str, list[str]]]]:
    """Two API processes limiting submissions to 10 per 4 s (rejected ones to 5) in one Redis;
    the client ``burst`` has three keys, ``sloppy`` and ``spammer`` one each."""
    env = dict(stack_env)
    env.update(
        DATABASE_URL=pg_schemas.new("rates"),
        TRAJOPT_QUEUE_NAME=f"trajopt-rates-{uuid.uuid4().hex[:10]}",
        TRAJOPT_RATE_WINDOW_S=str(WINDOW_S),
        TRAJOPT_RATE_SUBMIT_PER_WINDOW=str(PER_WINDOW),
        TRAJOPT_RATE_REJECTED_PER_WINDOW=str(REJECTED_PER_WINDOW),
        TRAJOPT_MAX_ACTIVE_JOBS="1000",
    )
    keys = {
        "burst": [create_api_key(env, "burst") for _ in range(3)],
        "sloppy": [create_api_key(env, "sloppy")],
        "spammer": [create_api_key(env, "spammer")],
    }
    logs = tmp_path_factory.mktemp("rates")
    servers = [ApiServer(env, logs / f"api-{i}.log") for i in range(2)]
    try:
        for server in servers:
            server.start_and_wait()
        yield [s.base_url for s in servers], keys
    finally:
        for server in servers:
            server.stop()
        forget_queue(env["REDIS_URL"], env["TRAJOPT_QUEUE_NAME"])


def sleep_until(when: float) -> None:
    """Sleep until the wall-clock time ``when``."""
    time.sleep(max(0.0, when - time.time()))


def test_the_moving_window_admits_exactly_the_limit_per_client_across_keys_and_processes(
    limited: tuple[list[str], dict[str, list[str]]],
) -> None:
    urls, keys = limited
    https = clients(urls)
    try:
        # Start 1 s before a fixed window's boundary (fixed windows are aligned on multiples
        # of their length), where fixed counters let a second full burst through.
        boundary = (time.time() // WINDOW_S + 1) * WINDOW_S
        if boundary - time.time() < 1.1:
            boundary += WINDOW_S
        sleep_until(boundary - 1.0)
        started = time.time()
        answers = burst(spread(https, keys["burst"], 3 * PER_WINDOW, QUICK))
        ended = time.time()
        assert codes(answers)[(202, "")] == PER_WINDOW, codes(answers)
        assert set(codes(answers)) == {(202, ""), (429, "rate_limited")}
        retry_after = {int(r.headers["retry-after"]) for r in answers if r.status_code == 429}
        # whole seconds until the oldest accepted request leaves the moving window: 1..window
        assert retry_after <= set(range(1, WINDOW_S + 1)), retry_after

        # Past the boundary but within a window of the accepted ones: nothing more.
        sleep_until(max(boundary + 0.2, ended))
        answers = burst(spread(https, keys["burst"], PER_WINDOW, QUICK))
        assert time.time() < started + WINDOW_S, "too slow to test inside one window"
        assert codes(answers) == {(429, "rate_limited"): PER_WINDOW}

        # A window after the accepted ones, the limit is available again, and only the limit.
        sleep_until(ended + WINDOW_S + 0.3)
        answers = burst(spread(https, keys["burst"], 3 * PER_WINDOW, QUICK))
        assert codes(answers)[(202, "")] == PER_WINDOW, codes(answers)
    finally:
        for http in https:
            http.close()


def test_rejected_submissions_do_not_use_the_submit_quota_but_are_bounded(
    limited: tuple[list[str], dict[str, list[str]]],
) -> None:
    urls, keys = limited
    https = clients(urls)
    try:
        started = time.time()
        sloppy, spammer = keys["sloppy"][0], keys["spammer"][0]
        answers = burst(spread(https, [sloppy], REJECTED_PER_WINDOW - 1, INVALID))
        assert codes(answers) == {(422, "invalid_request"): REJECTED_PER_WINDOW - 1}
        # The invalid bodies used none of the submit quota: the whole limit is accepted.
        answers = burst(spread(https, [sloppy], PER_WINDOW + 5, QUICK))
        assert codes(answers) == {(202, ""): PER_WINDOW, (429, "rate_limited"): 5}

        answers = burst(spread(https, [spammer], REJECTED_PER_WINDOW, INVALID))
        assert codes(answers) == {(422, "invalid_request"): REJECTED_PER_WINDOW}
        for body in (INVALID, QUICK):  # refused before validation until the window moves on
            refused = https[0].post("/v1/jobs", json=body, headers={"X-API-Key": spammer})
            assert refused.status_code == 429, refused.text
            error = refused.json()["error"]
            assert error["code"] == "rate_limited" and "rejected submissions" in error["message"]
            assert 1 <= int(refused.headers["retry-after"]) <= WINDOW_S
        assert time.time() < started + WINDOW_S, "too slow to test inside one window"
    finally:
        for http in https:
            http.close()
