"""The Python client's pure logic: server-sent event parsing, typed errors from the common error
body, the retry rule (connection failures and 429/502/503/504 after Retry-After or a back-off,
within the budget, with one Idempotency-Key; never other errors), and the event stream opened
again after a cut or a refusal. The transport is httpx's in-memory one; the same client against
real servers is in tests/e2e/test_client.py and tests/integration/test_client_recovery.py."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from app.client import (
    ConflictError,
    InvalidRequestError,
    NotFoundError,
    RateLimitedError,
    ServiceUnreachableError,
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
    """Answers requests from a list (an exception in it is raised instead), recording each
    request and each sleep."""

    def __init__(self, *answers: httpx.Response | Exception) -> None:
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
        answer = self.answers.pop(0)
        if isinstance(answer, Exception):
            raise answer
        return answer


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
    assert script.sleeps == [0.5]  # no Retry-After: exponential from 0.5 s


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


def test_a_lost_answer_is_tried_again_with_the_same_idempotency_key() -> None:
    job = {"id": "j1", "status": "queued"}
    script = Script(
        httpx.RemoteProtocolError("Server disconnected without sending a response."),
        httpx.ConnectError("connection refused"),
        httpx.ReadTimeout("timed out"),
        _error(502, "http_502"),
        httpx.Response(202, json=job),
    )
    assert script.client().submit({"scenario": "rlv-min-heat-load"}) == job
    assert script.sleeps == [0.5, 1.0, 2.0, 4.0]
    assert len({r.headers["Idempotency-Key"] for r in script.requests}) == 1


def test_no_answer_within_the_budget_is_a_typed_error() -> None:
    script = Script(*[httpx.ConnectError("connection refused") for _ in range(3)])
    with pytest.raises(ServiceUnreachableError) as raised:
        script.client(max_retries=2).job("j1")
    assert (raised.value.attempts, raised.value.waited_s) == (3, 1.5)
    assert isinstance(raised.value.__cause__, httpx.ConnectError)
    assert "cannot reach http://service after 3 tries over 2 s" in str(raised.value)


class CutStream(httpx.SyncByteStream):
    """An event stream's body that ends in a reset after ``chunks``."""

    def __init__(self, *chunks: bytes) -> None:
        self.chunks = chunks

    def __iter__(self) -> Iterator[bytes]:
        yield from self.chunks
        raise httpx.ReadError("connection reset by peer")


def _events(*blocks: str, cut: bool = False) -> httpx.Response:
    body = [block.encode() for block in blocks]
    headers = {"content-type": "text/event-stream"}
    if cut:
        return httpx.Response(200, headers=headers, stream=CutStream(*body))
    return httpx.Response(200, headers=headers, content=b"".join(body))


ITERATION = 'event: iteration\nid: {n}\ndata: {{"iteration": {n}}}\n\n'
END = 'event: end\ndata: {"id": "j1", "status": "succeeded"}\n\n'


def test_a_cut_stream_is_opened_again_after_its_last_event() -> None:
    script = Script(
        _events(ITERATION.format(n=1), ITERATION.format(n=2), cut=True),
        httpx.ConnectError("connection refused"),  # the API restarting
        _events(ITERATION.format(n=3), END),
    )
    records = list(script.client().iterations("j1"))
    assert [r["iteration"] for r in records] == [1, 2, 3]
    assert [r.headers.get("Last-Event-ID") for r in script.requests] == [None, "2", "2"]
    assert script.sleeps == [0.5, 1.0]


def test_wait_polls_while_its_stream_is_refused_and_survives_a_cut() -> None:
    running = httpx.Response(200, json={"id": "j1", "status": "running"})
    streams = _error(429, "too_many_streams", "5")
    script = Script(
        running,  # the job first
        streams,  # its stream refused: polled until the Retry-After
        running,
        running,
        _events(ITERATION.format(n=4), cut=True),  # opened again, then cut
        httpx.ConnectError("connection refused"),  # the poll after the cut, retried
        running,
        _events(END),
    )
    now = [0.0]
    client = script.client()
    client._sleep = lambda s: (script.sleeps.append(s), now.__setitem__(0, now[0] + s))
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr("app.client.time.monotonic", lambda: now[0])
        done = client.wait("j1", poll_s=3.0)
    assert done == {"id": "j1", "status": "succeeded"}
    paths = [r.url.path.rsplit("/", 1)[-1] for r in script.requests]
    assert paths == ["j1", "events", "j1", "j1", "events", "j1", "j1", "events"]
    assert script.requests[-1].headers["Last-Event-ID"] == "4"
    assert script.sleeps == [3.0, 3.0, 0.5, 3.0]  # two polls, the retried poll, one poll
