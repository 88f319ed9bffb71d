"""Server-sent events of one job: one ``iteration`` event per SCP iteration, a ``phase`` event
when the attempt starts compiling, optimizing or verifying, then one ``end``.

The database is the source of every event. A waker only decides when to look again: Redis
pub/sub notices from the workers when a broker is configured, a short poll otherwise.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import threading
from collections.abc import AsyncIterator, Callable
from contextlib import AbstractAsyncContextManager, asynccontextmanager
from dataclasses import dataclass
from datetime import datetime
from typing import Any, Protocol

import anyio.to_thread
import redis.asyncio as aioredis
from sqlalchemy import select
from sse_starlette.sse import ServerSentEvent

from app.storage.models import TERMINAL_STATUSES, Job
from app.storage.session import Database
from worker.notify import channel_for

log = logging.getLogger(__name__)

WaitFn = Callable[[float], Any]


class Waker(Protocol):
    """Gives an SSE stream a ``wait(timeout)`` that returns early when its job may have changed."""

    def subscribe(self, job_id: str) -> AbstractAsyncContextManager[WaitFn]:
        """Listen for changes of ``job_id`` while the context is open."""
        ...

    async def close(self) -> None:
        """Release connections."""


class PollingWaker:
    """Look again after a short interval, or at once when :meth:`notify` names the job.

    Used without Redis: the local pool's completion callback calls ``notify`` (from any thread),
    so the ``end`` event does not wait for the next poll.
    """

    def __init__(self, interval_s: float) -> None:
        self._interval = interval_s
        self._lock = threading.Lock()
        self._waiters: dict[str, set[tuple[asyncio.AbstractEventLoop, asyncio.Event]]] = {}

    def notify(self, job_id: str) -> None:
        """Wake the streams of ``job_id`` (thread-safe)."""
        with self._lock:
            waiters = list(self._waiters.get(job_id, ()))
        for loop, event in waiters:
            loop.call_soon_threadsafe(event.set)

    @asynccontextmanager
    async def subscribe(self, job_id: str) -> AsyncIterator[WaitFn]:
        """A wait that sleeps the poll interval unless the job is notified first."""
        entry = (asyncio.get_running_loop(), asyncio.Event())
        with self._lock:
            self._waiters.setdefault(job_id, set()).add(entry)

        async def wait(timeout: float) -> None:
            event = entry[1]
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(event.wait(), min(timeout, self._interval))
            event.clear()

        try:
            yield wait
        finally:
            with self._lock:
                waiters = self._waiters.get(job_id)
                if waiters is not None:
                    waiters.discard(entry)
                    if not waiters:
                        del self._waiters[job_id]

    async def close(self) -> None:
        """Nothing to release."""


class RedisWaker:
    """Wakes up on the workers' Redis notices; falls back to polling if Redis misbehaves."""

    def __init__(self, url: str, fallback_interval_s: float) -> None:
        self._url = url
        self._fallback = fallback_interval_s
        self._client: aioredis.Redis | None = None

    def _redis(self) -> aioredis.Redis:
        if self._client is None:
            self._client = aioredis.Redis.from_url(self._url)
        return self._client

    @asynccontextmanager
    async def subscribe(self, job_id: str) -> AsyncIterator[WaitFn]:
        """A wait that returns at the next notice of ``job_id`` (or after ``timeout``)."""
        pubsub = None
        try:
            pubsub = self._redis().pubsub()
            await pubsub.subscribe(channel_for(job_id))
        except Exception:
            log.warning("no Redis notices for job %s; polling instead", job_id, exc_info=True)
            pubsub = None

        async def wait(timeout: float) -> None:
            if pubsub is None:
                await asyncio.sleep(min(timeout, self._fallback))
                return
            try:
                message = await pubsub.get_message(ignore_subscribe_messages=True, timeout=timeout)
                while message is not None:  # drain: one database read covers them all
                    message = await pubsub.get_message(ignore_subscribe_messages=True, timeout=0)
            except Exception:
                log.warning("Redis notice wait failed", exc_info=True)
                await asyncio.sleep(min(timeout, self._fallback))

        try:
            yield wait
        finally:
            if pubsub is not None:
                try:
                    await pubsub.unsubscribe()
                    await pubsub.aclose()
                except Exception:
                    log.debug("closing a pubsub failed", exc_info=True)

    async def close(self) -> None:
        """Close the Redis connection pool."""
        if self._client is not None:
            await self._client.aclose()
            self._client = None


@dataclass(frozen=True)
class _Snapshot:
    status: str
    updated_at: datetime
    job: Job | None
    """The whole row when it changed since the previous read, else ``None``."""


def _read(database: Database, job_id: str, owner: str, since: datetime | None) -> _Snapshot | None:
    with database.reader() as session:
        head = session.execute(
            select(Job.status, Job.updated_at).where(Job.id == job_id, Job.owner == owner)
        ).one_or_none()
        if head is None:
            return None
        status, updated_at = head
        if since is not None and updated_at == since and status not in TERMINAL_STATUSES:
            return _Snapshot(status, updated_at, None)
        job = session.execute(select(Job).where(Job.id == job_id)).scalar_one()
        return _Snapshot(job.status, job.updated_at, job)


def _phase_of(job: Job) -> tuple[int, str] | None:
    """The running attempt's phase as (attempt, phase), if its progress names one."""
    progress = job.progress if isinstance(job.progress, dict) else {}
    name = progress.get("phase")
    return (job.attempts, name) if isinstance(name, str) else None


def parse_last_event_id(value: str | None) -> int:
    """Iterations a reconnecting client already has, from its ``Last-Event-ID`` header."""
    if value is None:
        return 0
    try:
        return max(0, int(value.strip()))
    except ValueError:
        return 0


async def job_events(
    *,
    database: Database,
    waker: Waker,
    job_id: str,
    owner: str,
    end_payload: Callable[[Job], Any],
    after: int = 0,
    idle_wait_s: float = 1.0,
) -> AsyncIterator[ServerSentEvent]:
    """Stream the job's iterations from number ``after + 1`` on, then a final ``end`` event.

    ``end_payload`` turns the finished job's row into the data of the ``end`` event.
    """
    sent = after
    attempts: int | None = None
    phase: tuple[int, str] | None = None
    since: datetime | None = None
    async with waker.subscribe(job_id) as wait:
        while True:
            snap = await anyio.to_thread.run_sync(_read, database, job_id, owner, since)
            if snap is None:
                return
            job = snap.job
            if job is not None:
                since = snap.updated_at
                if attempts is not None and job.attempts != attempts:
                    sent = 0  # a new attempt starts its history again
                attempts = job.attempts
                history = list(job.history or [])
                for index in range(sent, len(history)):
                    data = {"job_id": job_id, "attempt": job.attempts, **history[index]}
                    yield ServerSentEvent(
                        data=json.dumps(data), event="iteration", id=str(index + 1)
                    )
                sent = max(sent, len(history))
                now = _phase_of(job)
                if now is not None and now != phase and job.status not in TERMINAL_STATUSES:
                    phase = now
                    data = {"job_id": job_id, "attempt": now[0], "phase": now[1]}
                    data["elapsed_s"] = (job.progress or {}).get("elapsed_s")
                    yield ServerSentEvent(data=json.dumps(data), event="phase")
                if job.status in TERMINAL_STATUSES:
                    payload = json.dumps(end_payload(job))
                    yield ServerSentEvent(data=payload, event="end", id=str(sent + 1))
                    return
            await wait(idle_wait_s)
