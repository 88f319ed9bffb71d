"""A Python client of the trajopt service: submit, follow, wait for, fetch, cancel and list jobs.

    from app.client import TrajoptClient

    with TrajoptClient("http://127.0.0.1:8000", api_key=None) as client:
        job = client.submit_scenario("rlv-min-heat-load", method={"nodes": 61})
        for record in client.iterations(job["id"]):  # live, one per SCP iteration
            print(record["iteration"], record["cost"])
        result = client.result(job["id"])

Every 4xx/5xx answer raises an :class:`ApiError` subclass carrying the service's error code,
message, field and (422) the list of field issues. What may pass is retried: a connection that
fails (refused, reset, cut before the answer, an answer that does not come within
``timeout_s``) and an answer that means "not now" (429 rate limit or active-job cap, 502, 503
queue or database unavailable, 504), after the ``Retry-After`` the service sends or else 0.5,
1, 2, 4, 8 s, up to ``max_retries`` times (5) and ``max_retry_wait_s`` (120 s) of waiting in all;
then the refusal's :class:`ApiError`, or :class:`ServiceUnreachableError` when no answer came.
A submission carries an ``Idempotency-Key`` (made here unless given) that its retries repeat,
so a submission whose answer was lost makes one job, not two. :meth:`TrajoptClient.wait`
follows the event stream and, when the stream is refused (429 ``too_many_streams``) or cut (an
API restart), polls the job and opens the stream again where it left off. It needs only
``httpx``, not the service's own code.
"""

from __future__ import annotations

import contextlib
import json
import time
import uuid
from collections.abc import Iterator, Mapping
from types import TracebackType
from typing import Any, Self

import httpx

TERMINAL = frozenset({"succeeded", "failed", "cancelled", "timed_out"})
"""Job statuses that do not change any more."""

RETRIED_STATUSES = frozenset({429, 502, 503, 504})
"""Answers that mean "not now": retried after their Retry-After (or a back-off)."""

RETRIED_ERRORS: tuple[type[Exception], ...] = (
    httpx.ConnectError,
    httpx.ConnectTimeout,
    httpx.ReadTimeout,
    httpx.WriteTimeout,
    httpx.PoolTimeout,
    httpx.ReadError,
    httpx.WriteError,
    httpx.RemoteProtocolError,
)
"""Failures of a connection that a new try may not meet: refused, reset, cut before the answer
(a restarting API, a proxy), no answer in time."""

STREAM_CUTS: tuple[type[Exception], ...] = tuple(
    kind for kind in RETRIED_ERRORS if kind is not httpx.ReadTimeout
)
"""The failures after which an event stream is opened again (a stream silent for its
``timeout_s`` ends as the caller asked)."""


class ApiError(Exception):
    """The service refused a request: HTTP ``status``, its error ``code``, ``message``,
    ``field`` (the first bad field, if any) and ``issues`` (every bad field, on 422)."""

    def __init__(
        self,
        status: int,
        code: str,
        message: str,
        field: str | None = None,
        issues: list[dict[str, Any]] | None = None,
        retry_after_s: float | None = None,
    ) -> None:
        super().__init__(f"{status} {code}: {message}")
        self.status = status
        self.code = code
        self.message = message
        self.field = field
        self.issues = issues or []
        self.retry_after_s = retry_after_s

    @property
    def fields(self) -> list[str]:
        """The fields named by the issues (or the one ``field``)."""
        named = [str(issue.get("field")) for issue in self.issues if issue.get("field")]
        return named or ([self.field] if self.field else [])


class InvalidRequestError(ApiError):
    """422: the problem (or the request) is invalid; ``issues`` lists every bad field."""


class AuthenticationError(ApiError):
    """401: no API key, or a key the service does not accept."""


class NotFoundError(ApiError):
    """404: no such job of yours (or scenario, or plot)."""


class ConflictError(ApiError):
    """409: not finished yet, finished without a result, or already finished."""


class RateLimitedError(ApiError):
    """429 after the retries: rate limit or active-job cap; ``retry_after_s`` says when."""


class UnavailableError(ApiError):
    """503 after the retries: the queue or the database is unreachable."""


class ServiceUnreachableError(ConnectionError):
    """No answer from the service after the retries: ``attempts`` tries over ``waited_s``
    seconds of waiting; the last connection failure is the ``__cause__``."""

    def __init__(self, base_url: str, attempts: int, waited_s: float, last: Exception) -> None:
        super().__init__(
            f"cannot reach {base_url} after {attempts} tries over {waited_s:.0f} s: "
            f"{type(last).__name__}: {last}"
        )
        self.attempts = attempts
        self.waited_s = waited_s


class JobTimeoutError(TimeoutError):
    """:meth:`TrajoptClient.wait` ran out of time; ``job`` is the job as last seen."""

    def __init__(self, job: dict[str, Any], timeout_s: float) -> None:
        super().__init__(f"job {job.get('id')} still {job.get('status')} after {timeout_s} s")
        self.job = job


_ERRORS: dict[int, type[ApiError]] = {
    401: AuthenticationError,
    404: NotFoundError,
    409: ConflictError,
    422: InvalidRequestError,
    429: RateLimitedError,
    503: UnavailableError,
}


def _retry_after(response: httpx.Response) -> float | None:
    """The Retry-After of an answer in seconds (the service sends whole seconds), or None."""
    value = response.headers.get("retry-after")
    try:
        return max(float(value), 0.0) if value is not None else None
    except ValueError:
        return None


def error_from(response: httpx.Response) -> ApiError:
    """The typed error of a refused request, from the service's common error body."""
    try:
        body = response.json()
        error = body.get("error") if isinstance(body, dict) else None
    except ValueError:
        error = None
    if not isinstance(error, dict):
        error = {"code": f"http_{response.status_code}", "message": response.text[:200]}
    kind = _ERRORS.get(response.status_code, ApiError)
    return kind(
        response.status_code,
        str(error.get("code")),
        str(error.get("message")),
        error.get("field"),
        error.get("issues"),
        _retry_after(response),
    )


def parse_events(lines: Iterator[str]) -> Iterator[tuple[str, Any]]:
    """(event, data) of each server-sent event in ``lines`` (text lines without their ends);
    comments (pings) are skipped, data is decoded as JSON."""
    for event, data, _ in parse_event_records(lines):
        yield event, data


def parse_event_records(lines: Iterator[str]) -> Iterator[tuple[str, Any, str | None]]:
    """(event, data, id) of each server-sent event in ``lines``, as :func:`parse_events`; id is
    the event's ``id:`` field (None without one)."""
    event, data, ident = "message", list[str](), None
    for line in lines:
        if line == "":
            if data:
                yield event, json.loads("\n".join(data)), ident
            event, data, ident = "message", [], None
            continue
        if line.startswith(":"):
            continue
        field, _, value = line.partition(":")
        value = value[1:] if value.startswith(" ") else value
        if field == "event":
            event = value
        elif field == "data":
            data.append(value)
        elif field == "id":
            ident = value
    if data:
        yield event, json.loads("\n".join(data)), ident


class RetryBudget:
    """The waits of one operation's retries: the refusal's Retry-After, else 0.5, 1, 2, 4, ...
    s; at most ``max_retries`` of them and ``max_wait_s`` in all."""

    def __init__(self, max_retries: int, max_wait_s: float) -> None:
        self.max_retries = max_retries
        self.max_wait_s = max_wait_s
        self.retries = 0
        self.waited_s = 0.0

    def next_wait(self, retry_after_s: float | None) -> float | None:
        """How long to wait before the next try, or None when the budget is spent."""
        wait = retry_after_s if retry_after_s is not None else 0.5 * 2.0**self.retries
        if self.retries >= self.max_retries or self.waited_s + wait > self.max_wait_s:
            return None
        self.retries += 1
        self.waited_s += wait
        return wait


class TrajoptClient:
    """A client of one trajopt service at ``base_url`` (``api_key`` for its api-keys mode)."""

    def __init__(
        self,
        base_url: str,
        api_key: str | None = None,
        *,
        timeout_s: float = 30.0,
        max_retries: int = 5,
        max_retry_wait_s: float = 120.0,
        transport: httpx.BaseTransport | None = None,
        sleep: Any = time.sleep,
    ) -> None:
        """``max_retries`` and ``max_retry_wait_s`` bound the retries of 429/503 answers;
        ``transport`` and ``sleep`` exist for tests of the retry logic."""
        headers = {"X-API-Key": api_key} if api_key else {}
        self.http = httpx.Client(
            base_url=base_url.rstrip("/"), headers=headers, timeout=timeout_s, transport=transport
        )
        self.max_retries = max_retries
        self.max_retry_wait_s = max_retry_wait_s
        self._sleep = sleep

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        value: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        """Close the connections."""
        self.http.close()

    # --- requests ------------------------------------------------------------------------

    def request(self, method: str, path: str, **kwargs: Any) -> httpx.Response:
        """One request, tried again (within the retry budget) while the connection fails or the
        service answers "not now" (:data:`RETRIED_STATUSES`); a refusal raises its typed
        :class:`ApiError`, no answer at all :class:`ServiceUnreachableError`."""
        budget = self._budget()
        while True:
            try:
                response = self.http.request(method, path, **kwargs)
            except RETRIED_ERRORS as exc:
                wait = budget.next_wait(None)
                if wait is None:
                    raise self._unreachable(budget, exc) from exc
                self._sleep(wait)
                continue
            if response.status_code < 400:
                return response
            error = error_from(response)
            retried = response.status_code in RETRIED_STATUSES
            wait = budget.next_wait(error.retry_after_s) if retried else None
            if wait is None:
                raise error
            self._sleep(wait)

    def _budget(self) -> RetryBudget:
        return RetryBudget(self.max_retries, self.max_retry_wait_s)

    def _unreachable(self, budget: RetryBudget, last: Exception) -> ServiceUnreachableError:
        return ServiceUnreachableError(
            str(self.http.base_url), budget.retries + 1, budget.waited_s, last
        )

    def _json(self, path: str, **params: Any) -> Any:
        return self.request("GET", path, params=params or None).json()

    # --- jobs ----------------------------------------------------------------------------

    def submit(self, body: Mapping[str, Any], idempotency_key: str | None = None) -> dict[str, Any]:
        """Submit a problem document, or ``{"scenario", "overrides", "method"}``; the job
        (queued). The same ``idempotency_key`` and body return the same job."""
        key = idempotency_key or str(uuid.uuid4())
        response = self.request(
            "POST", "/v1/jobs", json=dict(body), headers={"Idempotency-Key": key}
        )
        job: dict[str, Any] = response.json()
        return job

    def submit_scenario(
        self,
        name: str,
        *,
        overrides: Mapping[str, Any] | None = None,
        method: Mapping[str, Any] | None = None,
        idempotency_key: str | None = None,
    ) -> dict[str, Any]:
        """Submit built-in scenario ``name`` with a JSON Merge Patch of its problem and method
        options merged into its method."""
        body: dict[str, Any] = {"scenario": name}
        if overrides:
            body["overrides"] = dict(overrides)
        if method:
            body["method"] = dict(method)
        return self.submit(body, idempotency_key)

    def job(self, job_id: str) -> dict[str, Any]:
        """The job: status, attempts, live progress."""
        job: dict[str, Any] = self._json(f"/v1/jobs/{job_id}")
        return job

    def wait(self, job_id: str, timeout_s: float = 600.0, poll_s: float = 0.5) -> dict[str, Any]:
        """The job once finished (any terminal status); :class:`JobTimeoutError` after
        ``timeout_s``. Follows the event stream; while the stream is refused (429
        ``too_many_streams``: until its Retry-After) or after it was cut (an API restart), the
        job is polled every ``poll_s`` and the stream opened again from its last event. Once
        the job was seen, a service out of reach is polled until ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        job = self.job(job_id)
        last_id: str | None = None
        stream_at = 0.0
        while job["status"] not in TERMINAL:
            left = deadline - time.monotonic()
            if left <= 0:
                raise JobTimeoutError(job, timeout_s)
            if time.monotonic() >= stream_at:
                try:
                    for event, data, ident in self._stream(job_id, left, last_id):
                        last_id = ident or last_id
                        if event == "end":
                            return dict(data)
                except ApiError as exc:
                    if exc.status not in RETRIED_STATUSES:
                        raise
                    stream_at = time.monotonic() + (exc.retry_after_s or poll_s)
                except STREAM_CUTS:
                    pass  # cut: poll, then open it again
                except httpx.ReadTimeout:
                    pass  # silent until the deadline: poll once more
            with contextlib.suppress(ServiceUnreachableError):  # restarting: try again
                job = self.job(job_id)
            if job["status"] not in TERMINAL:
                self._sleep(min(poll_s, max(deadline - time.monotonic(), 0.0)))
        return job

    def events(self, job_id: str, timeout_s: float | None = None) -> Iterator[tuple[str, Any]]:
        """The job's server-sent events as (event, data): ``iteration`` records, ``phase``
        changes, then ``end`` (the finished job); replayed from the start for a finished job.
        A stream cut before its end, or refused for a while, is opened again (within the retry
        budget, which each event received renews) from the last event received; ``timeout_s``
        is the longest silence accepted (the service pings idle streams)."""
        last_id: str | None = None
        budget = self._budget()
        while True:
            failure: Exception
            try:
                for event, data, ident in self._stream(job_id, timeout_s, last_id):
                    last_id, budget = ident or last_id, self._budget()
                    yield event, data
                    if event == "end":
                        return
                failure = httpx.RemoteProtocolError("the stream ended before its end event")
            except ApiError as exc:
                if exc.status not in RETRIED_STATUSES:
                    raise
                failure = exc
            except STREAM_CUTS as exc:
                failure = exc
            retry_after = failure.retry_after_s if isinstance(failure, ApiError) else None
            wait = budget.next_wait(retry_after)
            if wait is None:
                if isinstance(failure, ApiError):
                    raise failure
                raise self._unreachable(budget, failure) from failure
            self._sleep(wait)

    def _stream(
        self, job_id: str, timeout_s: float | None, last_id: str | None
    ) -> Iterator[tuple[str, Any, str | None]]:
        """One event stream of the job, from after event ``last_id`` (all when None); a refusal
        raises its :class:`ApiError`."""
        timeout = httpx.Timeout(self.http.timeout.connect, read=timeout_s)
        headers = {"Last-Event-ID": last_id} if last_id else None
        path = f"/v1/jobs/{job_id}/events"
        with self.http.stream("GET", path, timeout=timeout, headers=headers) as response:
            if response.status_code >= 400:
                response.read()
                raise error_from(response)
            yield from parse_event_records(response.iter_lines())

    def iterations(self, job_id: str, timeout_s: float | None = None) -> Iterator[dict[str, Any]]:
        """Each iteration record of the job as it arrives, until the job ends."""
        for event, data in self.events(job_id, timeout_s):
            if event == "iteration":
                yield dict(data)
            elif event == "end":
                return

    def result(self, job_id: str) -> dict[str, Any]:
        """The result document of a finished job (:class:`ConflictError` before)."""
        result: dict[str, Any] = self._json(f"/v1/jobs/{job_id}/result")
        return result

    def problem(self, job_id: str) -> dict[str, Any]:
        """The problem document the job solves, normalized (defaults filled in) after its
        scenario, overrides and start were applied: its canonical JSON hashes to the result's
        ``provenance.problem_sha256``."""
        problem: dict[str, Any] = self._json(f"/v1/jobs/{job_id}/problem")
        return problem

    def history(self, job_id: str) -> list[dict[str, Any]]:
        """The iteration records so far."""
        return list(self._json(f"/v1/jobs/{job_id}/history")["iterations"])

    def trajectory_csv(self, job_id: str) -> str:
        """The result's trajectory as CSV text."""
        return self.request("GET", f"/v1/jobs/{job_id}/trajectory.csv").text

    def plots(self, job_id: str) -> list[str]:
        """The names of the result's plots."""
        return list(self._json(f"/v1/jobs/{job_id}/plots"))

    def plot(self, job_id: str, name: str, fmt: str = "png") -> bytes:
        """Plot ``name`` of the result as PNG or SVG bytes."""
        return self.request("GET", f"/v1/jobs/{job_id}/plots/{name}.{fmt}").content

    def cancel(self, job_id: str) -> dict[str, Any]:
        """Cancel the job (a queued one at once, a running one at its next iteration)."""
        job: dict[str, Any] = self.request("DELETE", f"/v1/jobs/{job_id}").json()
        return job

    def jobs(self, status: str | None = None, page_size: int = 100) -> Iterator[dict[str, Any]]:
        """The caller's jobs, newest first (optionally of one status), page after page."""
        offset: int | None = 0
        while offset is not None:
            params: dict[str, Any] = {"limit": page_size, "offset": offset}
            if status:
                params["status"] = status
            page = self._json("/v1/jobs", **params)
            yield from page["items"]
            offset = page.get("next_offset")

    def validate(self, problem: Mapping[str, Any]) -> dict[str, Any]:
        """The problem normalized by the service (defaults filled in), or InvalidRequestError."""
        answer: dict[str, Any] = self.request(
            "POST", "/v1/problems/validate", json=dict(problem)
        ).json()
        return answer

    # --- batches -------------------------------------------------------------------------

    def submit_batch(
        self, body: Mapping[str, Any], idempotency_key: str | None = None
    ) -> dict[str, Any]:
        """Submit a batch: ``{"base", "grid" | "monte_carlo" | "methods", "name"}``."""
        key = idempotency_key or str(uuid.uuid4())
        response = self.request(
            "POST", "/v1/batches", json=dict(body), headers={"Idempotency-Key": key}
        )
        batch: dict[str, Any] = response.json()
        return batch

    def batch(self, batch_id: str) -> dict[str, Any]:
        """The batch: status and its children counted by status."""
        batch: dict[str, Any] = self._json(f"/v1/batches/{batch_id}")
        return batch

    def wait_batch(
        self, batch_id: str, timeout_s: float = 3600.0, poll_s: float = 1.0
    ) -> dict[str, Any]:
        """The batch once no child is queued or running; :class:`JobTimeoutError` after
        ``timeout_s`` (its ``job`` is the batch as last seen)."""
        deadline = time.monotonic() + timeout_s
        batch = self.batch(batch_id)
        while batch["status"] == "running":
            if time.monotonic() >= deadline:
                raise JobTimeoutError(batch, timeout_s)
            self._sleep(poll_s)
            batch = self.batch(batch_id)
        return batch

    def batch_summary(self, batch_id: str) -> dict[str, Any]:
        """One row per child: parameters, status, objective, terminal and path figures."""
        summary: dict[str, Any] = self._json(f"/v1/batches/{batch_id}/summary")
        return summary

    def batch_summary_csv(self, batch_id: str) -> str:
        """The summary as CSV text."""
        return self.request("GET", f"/v1/batches/{batch_id}/summary.csv").text

    def batch_plot(self, batch_id: str, fmt: str = "png") -> bytes:
        """The batch's plot as PNG or SVG bytes."""
        return self.request("GET", f"/v1/batches/{batch_id}/plot.{fmt}").content

    def cancel_batch(self, batch_id: str) -> dict[str, Any]:
        """Cancel the batch's children not finished yet."""
        batch: dict[str, Any] = self.request("DELETE", f"/v1/batches/{batch_id}").json()
        return batch
