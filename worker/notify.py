"""Wake-up notices for live event streams: the worker publishes, the API's SSE handlers listen.

The database stays the source of truth; a notice only says "job X changed, read it again", so a
lost notice costs latency, never data.
"""

from __future__ import annotations

import logging
import os

import redis

from app.failure_log import FailureLog

log = logging.getLogger(__name__)

CHANNEL_PREFIX = "trajopt:job:"


def channel_for(job_id: str) -> str:
    """The pub/sub channel of one job."""
    return CHANNEL_PREFIX + job_id


class RedisNotifier:
    """Publishes ``iteration``/``end`` notices of a job on Redis (one client per process)."""

    def __init__(self, url: str) -> None:
        self._url = url
        self._client: redis.Redis | None = None
        self._pid = 0
        self._failures = FailureLog(log, "event notices")

    def _redis(self) -> redis.Redis:
        if self._client is None or self._pid != os.getpid():
            self._client = redis.Redis.from_url(self._url, socket_timeout=2.0)
            self._pid = os.getpid()
        return self._client

    def __call__(self, job_id: str, kind: str) -> None:
        """Publish ``kind`` for ``job_id``; failures are logged, never raised."""
        try:
            self._redis().publish(channel_for(job_id), kind)
        except redis.RedisError as exc:
            self._failures.failed(exc, f"publish the {kind} notice of job {job_id}", "skipped")
            return
        self._failures.succeeded("published again")
