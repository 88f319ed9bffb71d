"""The Python client's pure logic: server-sent event parsing, typed errors from the common error
body, and the retry rule (429/503 after Retry-After, within the budget; never other errors).
The transport is httpx's in-memory one; the same client against a real server is in
tests/e2e/test_client.py."""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from app.client import (
    ConflictError,
    InvalidRequestError,
    NotFoundError,
    RateLimitedError,
    TrajoptClient,
    UnavailableError,
    parse_events,
)


def test_events_are_parsed_with_comments_and_multiline_data() -> None:
    lines = [
        ": ping",
        "event: iteration",
        "id: 1",
        'data: {"iteration": 1,',
        'data:  "cost": 2.5}',
        "",
        "",
        "event: end",
        'data: {"status": "succeeded"}',
    ]
    assert list(parse_events(iter(lines))) == [
        ("iteration", {"iteration": 1, "cost": 2.5}),
        ("end", {"status": "succeeded"}),
    ]


def _error(status: int, code: str, retry_after: str | None = None, **extra: Any) -> httpx.Response:
    headers = {"Retry-After": retry_after} if retry_after is not None else {}
    body = {"error": {"code": code, "message": f"{code} happened", "field": None, **extra}}
    return httpx.Response(status, json=body, headers=headers)


class Script:
    """Answers requests from a list, recording each request and each sleep."""

    def __init__(self, *answers: httpx.Response) -> None:
        self.answers = list(answers)
        self.requests: list[httpx.Request] = []
        self.sleeps: list[float] = []

    def client(self, **options: Any) -> TrajoptClient:
        transport = httpx.MockTransport(self.handle)
        return TrajoptClient(
            "http://service", "tk_key", transport=transport, sleep=self.sleeps.append, **options
        )

    def handle(self, request: httpx.Request) -> httpx.Response:
        self.requests.append(request)
        return self.answers.pop(0)


def test_a_busy_service_is_retried_after_its_retry_after_with_one_idempotency_key() -> None:
    job = {"id": "j1", "status": "queued"}
    script = Script(
        _error(503, "queue_unavailable", "2"),
        _error(429, "too_many_active_jobs", "5"),
        httpx.Response(202, json=job),
    )
    assert script.client().submit_scenario("rlv-min-heat-load", method={"nodes": 20}) == job
    assert script.sleeps == [2.0, 5.0]
    keys = {r.headers["Idempotency-Key"] for r in script.requests}
    assert len(keys) == 1 and len(script.requests) == 3  # one job, however many tries
    assert all(r.headers["X-API-Key"] == "tk_key" for r in script.requests)


def test_retries_stop_at_the_budget_with_the_typed_error() -> None:
    script = Script(*[_error(429, "rate_limited", "30") for _ in range(3)])
    with pytest.raises(RateLimitedError) as raised:
        script.client(max_retries=5, max_retry_wait_s=60.0).job("j1")
    assert script.sleeps == [30.0, 30.0]  # a third wait would pass the 60 s budget
    assert raised.value.retry_after_s == 30.0 and raised.value.code == "rate_limited"
    script = Script(*[_error(503, "database_unavailable") for _ in range(2)])
    with pytest.raises(UnavailableError):
        script.client(max_retries=1).job("j1")
    assert script.sleeps == [1.0]  # no Retry-After: exponential from 1 s


@pytest.mark.parametrize(
    ("response", "kind"),
    [
        (_error(404, "job_not_found"), NotFoundError),
        (_error(409, "job_not_finished"), ConflictError),
        (httpx.Response(500, text="<html>oops</html>"), Exception),
    ],
)
def test_other_refusals_are_raised_at_once(response: httpx.Response, kind: type[Exception]) -> None:
    script = Script(response)
    with pytest.raises(kind) as raised:
        script.client().result("j1")
    assert script.sleeps == []
    if response.status_code == 500:
        assert getattr(raised.value, "code", None) == "http_500"


def test_a_422_carries_every_bad_field() -> None:
    issues = [
        {"field": "vehicle.mass_kg", "message": "Input should be greater than 0", "code": "x"},
        {"field": "method.nodes", "message": "too few", "code": "y"},
    ]
    script = Script(_error(422, "invalid_problem", issues=issues))
    with pytest.raises(InvalidRequestError) as raised:
        script.client().submit({"vehicle": {}})
    assert raised.value.fields == ["vehicle.mass_kg", "method.nodes"]
    assert raised.value.status == 422 and script.sleeps == []
