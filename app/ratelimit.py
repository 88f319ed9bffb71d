"""Per-key request rate limits in fixed windows: shared in Redis, or in this process's memory.

With a broker configured every API process counts in the same Redis keys, so the limit holds
across processes. If Redis stops answering, counting falls back to memory for a short while
rather than failing requests (the broker outage is handled where it matters: submissions).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from typing import Protocol

import redis

log = logging.getLogger(__name__)

FALLBACK_S = 5.0
"""How long the Redis limiter counts in memory after a Redis error before trying Redis again."""


class RateLimiter(Protocol):
    """Counts hits per bucket and window."""

    def hit(self, bucket: str, limit: int, window_s: float) -> float | None:
        """Count one hit; ``None`` if within ``limit``, else seconds until the window ends."""

    def close(self) -> None:
        """Release connections."""


def _window(window_s: float, now: float) -> tuple[int, float]:
    index = int(now // window_s)
    return index, max(1.0, math.ceil((index + 1) * window_s - now))


class MemoryRateLimiter:
    """Fixed-window counters in a dict (one API process)."""

    def __init__(self, clock: object = time.time) -> None:
        self._clock = clock
        self._lock = threading.Lock()
        self._counts: dict[tuple[str, int], int] = {}

    def hit(self, bucket: str, limit: int, window_s: float) -> float | None:
        """Count one hit in the current window of ``bucket``."""
        if limit <= 0:
            return None
        now = float(self._clock())  # type: ignore[operator]
        index, retry_after = _window(window_s, now)
        with self._lock:
            key = (bucket, index)
            count = self._counts.get(key, 0) + 1
            self._counts[key] = count
            if len(self._counts) > 10_000:
                self._counts = {k: v for k, v in self._counts.items() if k[1] >= index}
        return None if count <= limit else retry_after

    def close(self) -> None:
        """Nothing to release."""


class RedisRateLimiter:
    """Fixed-window counters in Redis (``INCR`` + ``EXPIRE``), shared by every API process."""

    def __init__(self, url: str, namespace: str, timeout_s: float) -> None:
        self._redis = redis.Redis.from_url(
            url, socket_timeout=timeout_s, socket_connect_timeout=timeout_s
        )
        self._namespace = namespace
        self._memory = MemoryRateLimiter()
        self._fallback_until = 0.0

    def hit(self, bucket: str, limit: int, window_s: float) -> float | None:
        """Count one hit; falls back to memory for a few seconds when Redis fails."""
        if limit <= 0:
            return None
        now = time.time()
        if now < self._fallback_until:
            return self._memory.hit(bucket, limit, window_s)
        index, retry_after = _window(window_s, now)
        key = f"trajopt:rate:{self._namespace}:{bucket}:{index}"
        try:
            pipe = self._redis.pipeline(transaction=True)
            pipe.incr(key)
            pipe.expire(key, math.ceil(window_s) + 1)
            count = int(pipe.execute()[0])
        except redis.RedisError as exc:
            log.warning("rate limiter: Redis unavailable (%s); counting in memory", exc)
            self._fallback_until = now + FALLBACK_S
            return self._memory.hit(bucket, limit, window_s)
        return None if count <= limit else retry_after

    def close(self) -> None:
        """Close the Redis connections."""
        self._redis.close()
