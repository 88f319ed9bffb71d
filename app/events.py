"""Wake-up notices for the server-sent event streams, and the ``Last-Event-ID`` of a reconnect.

The database is the source of every event (see :mod:`app.stream_hub`). A waker only tells the
process's one stream watcher when to look again: Redis pub/sub notices from the workers when a
broker is configured (one connection per process, one pattern subscription for every job), the
local pool's completion callback and a short poll otherwise.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
from collections.abc import Callable
from typing import Protocol

import redis.asyncio as aioredis

from worker.notify import CHANNEL_PREFIX

log = logging.getLogger(__name__)

NoticeFn = Callable[[str | None, bool], None]
"""Called on the event loop with the id of a job that may have changed (``None``: any job) and
whether the notice says the job's attempt ended (its ``end`` is read at once, see
:mod:`app.stream_hub`)."""

IDLE_REREAD_S = 1.0
"""With live Redis notices, every watched job is still read again this often (a lost notice
costs at most this much latency)."""

REDIS_RETRY_S = 2.0
"""Pause before the Redis listener connects again after a failure."""


class Waker(Protocol):
    """The process-wide source of "job X may have changed" notices for the stream watcher."""

    def poll_interval(self) -> float:
        """How long the watcher waits for a notice before reading every watched job again."""
        ...

    async def start(self, on_notice: NoticeFn) -> None:
        """Deliver notices to ``on_notice`` (on the running loop) from now on."""
        ...

    async def close(self) -> None:
        """Stop delivering notices and release connections."""
        ...


class PollingWaker:
    """Look again after a short interval, or at once when :meth:`notify` names the job.

    Used without Redis: the local pool's completion callback calls ``notify`` (from any thread),
    so the ``end`` event does not wait for the next poll.
    """

    def __init__(self, interval_s: float) -> None:
        self._interval = interval_s
        self._lock = threading.Lock()
        self._sink: tuple[asyncio.AbstractEventLoop, NoticeFn] | None = None

    def poll_interval(self) -> float:
        """The configured poll interval."""
        return self._interval

    async def start(self, on_notice: NoticeFn) -> None:
        """Deliver :meth:`notify` calls to ``on_notice`` on the running loop."""
        with self._lock:
            self._sink = (asyncio.get_running_loop(), on_notice)

    def notify(self, job_id: str) -> None:
        """Tell the watcher that ``job_id`` ended (thread-safe; a no-op before ``start``): the
        local pool calls this when a job is done."""
        with self._lock:
            sink = self._sink
        if sink is None:
            return
        loop, on_notice = sink
        with contextlib.suppress(RuntimeError):  # the loop closed at shutdown
            loop.call_soon_threadsafe(on_notice, job_id, True)

    async def close(self) -> None:
        """Stop delivering notices."""
        with self._lock:
            self._sink = None


class RedisWaker:
    """One Redis connection per process subscribed to every job's notice channel (a pattern).

    Each API process hears every job's notices and drops those of jobs it does not stream: a
    notice is a few bytes per solver iteration, far cheaper than a subscription per stream. While
    Redis is unreachable the watcher polls every ``fallback_interval_s`` instead, and the listener
    reconnects every :data:`REDIS_RETRY_S`.
    """

    def __init__(self, url: str, fallback_interval_s: float) -> None:
        self._url = url
        self._fallback = fallback_interval_s
        self._task: asyncio.Task[None] | None = None
        self._listening = False

    def poll_interval(self) -> float:
        """:data:`IDLE_REREAD_S` while notices arrive, the fallback poll while Redis is away."""
        return IDLE_REREAD_S if self._listening else min(self._fallback, IDLE_REREAD_S)

    async def start(self, on_notice: NoticeFn) -> None:
        """Start the listener task (once)."""
        if self._task is None:
            self._task = asyncio.create_task(self._listen(on_notice), name="trajopt-notices")

    async def _listen(self, on_notice: NoticeFn) -> None:
        failures = 0
        while True:
            client = aioredis.Redis.from_url(self._url, socket_connect_timeout=2.0)
            pubsub = client.pubsub(ignore_subscribe_messages=True)
            try:
                await pubsub.psubscribe(CHANNEL_PREFIX + "*")
                self._listening = True
                if failures:
                    log.info("Redis notices for event streams are back")
                    on_notice(None, False)  # notices may have been lost meanwhile
                failures = 0
                while True:
                    message = await pubsub.get_message(timeout=IDLE_REREAD_S)
                    if message is not None and message.get("type") == "pmessage":
                        channel = message["channel"]
                        if isinstance(channel, bytes):
                            channel = channel.decode("utf-8", "replace")
                        ended = message.get("data") in (b"end", "end")
                        on_notice(str(channel).removeprefix(CHANNEL_PREFIX), ended)
            except asyncio.CancelledError:
                raise
            except Exception as exc:
                self._listening = False
                failures += 1
                if failures == 1:  # once per outage, not once per retry
                    log.warning(
                        "no Redis notices for event streams (%s); polling every %g s until "
                        "Redis is back",
                        exc,
                        self.poll_interval(),
                    )
                await asyncio.sleep(REDIS_RETRY_S)
            finally:
                self._listening = False
                with contextlib.suppress(Exception):
                    await pubsub.aclose()
                with contextlib.suppress(Exception):
                    await client.aclose()

    async def close(self) -> None:
        """Stop the listener and close its connection."""
        task, self._task = self._task, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task


def parse_last_event_id(value: str | None) -> int:
    """Iterations a reconnecting client already has, from its ``Last-Event-ID`` header."""
    if value is None:
        return 0
    try:
        return max(0, int(value.strip()))
    except ValueError:
        return 0
