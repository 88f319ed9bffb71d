"""Request rate limits in moving windows, per client and per API key: shared in Redis, or in
this process's memory.

The counting is the ``limits`` package's moving window: a request is admitted when fewer than
``limit`` requests of its bucket were admitted in the last ``window`` seconds, so no boundary
lets a burst of twice the limit through, as fixed windows do. With a broker configured every
API process counts in the same Redis lists (one atomic Lua script per hit), so the limit holds
across processes. If Redis stops answering, counting falls back to memory for a short while
rather than failing requests (the broker outage is handled where it matters: submissions).

What each request costs (see :class:`Quota`): a read uses one unit of the read window. A
submission is first *tested* against the client's rejected-submission window, then (unless
it replays an Idempotency-Key, which costs a read) against its submit window, using nothing
so far; it uses one unit of the submit window only when it is accepted, or one unit of the
rejected window when it is refused with a 4xx after those tests (invalid problem, server cap,
active-job cap). Invalid bodies therefore never eat the submit quota, and are bounded all the
same. A 429 of the limiter itself uses nothing: it is the cheap answer.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import dataclass
from typing import Literal, Protocol
from urllib.parse import quote

import redis
from limits import RateLimitItemPerSecond
from limits.storage import MemoryStorage, RedisStorage
from limits.strategies import MovingWindowRateLimiter

from app.settings import Settings

log = logging.getLogger(__name__)

FALLBACK_S = 5.0
"""How long the Redis limiter counts in memory after a Redis error before trying Redis again."""
NAMESPACE = "trajopt"
"""The ``limits`` namespace of every bucket (the first part of each stored key)."""

Kind = Literal["read", "submit", "rejected"]


def window_seconds(window_s: float) -> int:
    """The moving window's length: whole seconds (``limits`` counts in seconds), at least 1."""
    return max(1, math.ceil(window_s))


def _item(limit: int, window_s: float) -> RateLimitItemPerSecond:
    return RateLimitItemPerSecond(limit, window_seconds(window_s), namespace=NAMESPACE)


class RateLimiter(Protocol):
    """Counts admitted hits per bucket in a moving window."""

    blocking: bool
    """Whether counting waits on I/O (Redis), so callers on an event loop hand it to a thread."""

    def hit(self, bucket: str, limit: int, window_s: float) -> float | None:
        """Count one hit; ``None`` if admitted, else seconds until the window admits one."""

    def test(self, bucket: str, limit: int, window_s: float) -> float | None:
        """Whether a hit would be admitted now, using nothing: ``None``, or the seconds to wait."""

    def close(self) -> None:
        """Release connections."""

    def quota(self, settings: Settings, client: str, key_id: str | None) -> Quota:
        """The limits of a request by ``client`` with the key ``key_id`` (``None``: no key)."""


class _MovingWindow:
    """A ``limits`` moving-window limiter over one storage."""

    def __init__(self, storage: MemoryStorage | RedisStorage) -> None:
        self._limiter = MovingWindowRateLimiter(storage)

    def _retry_after(self, item: RateLimitItemPerSecond, bucket: str) -> float:
        reset_at = self._limiter.get_window_stats(item, bucket).reset_time
        return float(max(1, math.ceil(reset_at - time.time())))

    def hit(self, bucket: str, limit: int, window_s: float) -> float | None:
        """Count one hit of ``bucket`` if the window admits it."""
        if limit <= 0:
            return None
        item = _item(limit, window_s)
        if self._limiter.hit(item, bucket):
            return None
        return self._retry_after(item, bucket)

    def test(self, bucket: str, limit: int, window_s: float) -> float | None:
        """Whether the window of ``bucket`` would admit a hit now."""
        if limit <= 0:
            return None
        item = _item(limit, window_s)
        if self._limiter.test(item, bucket):
            return None
        return self._retry_after(item, bucket)


class MemoryRateLimiter:
    """Moving windows in this process's memory (one API process: embedded mode)."""

    blocking = False

    def __init__(self) -> None:
        self._window = _MovingWindow(MemoryStorage())
        # ``limits`` locks each key, but drops an idle key's lock on its expiry timer; one lock
        # over these microsecond operations makes every hit exact under concurrent requests.
        self._lock = threading.Lock()

    def hit(self, bucket: str, limit: int, window_s: float) -> float | None:
        """Count one hit of ``bucket`` if its window admits it."""
        with self._lock:
            return self._window.hit(bucket, limit, window_s)

    def test(self, bucket: str, limit: int, window_s: float) -> float | None:
        """Whether the window of ``bucket`` would admit a hit now."""
        with self._lock:
            return self._window.test(bucket, limit, window_s)

    def close(self) -> None:
        """Nothing to release."""

    def quota(self, settings: Settings, client: str, key_id: str | None) -> Quota:
        """The limits of a request by ``client`` with the key ``key_id`` (``None``: no key)."""
        return Quota(self, settings, client, key_id)


class RedisRateLimiter:
    """Moving windows in Redis, shared by every API process using the same ``namespace``."""

    blocking = True

    def __init__(self, url: str, namespace: str, timeout_s: float) -> None:
        self._storage = RedisStorage(
            url,
            key_prefix=f"trajopt:rate:{namespace}",
            socket_timeout=timeout_s,
            socket_connect_timeout=timeout_s,
        )
        self._window = _MovingWindow(self._storage)
        self._memory = MemoryRateLimiter()
        self._fallback_until = 0.0

    def _fall_back(self, exc: redis.RedisError) -> None:
        log.warning("rate limiter: Redis unavailable (%s); counting in memory", exc)
        self._fallback_until = time.monotonic() + FALLBACK_S

    def hit(self, bucket: str, limit: int, window_s: float) -> float | None:
        """Count one hit; falls back to memory for a few seconds when Redis fails."""
        if limit > 0 and time.monotonic() >= self._fallback_until:
            try:
                return self._window.hit(bucket, limit, window_s)
            except redis.RedisError as exc:
                self._fall_back(exc)
        return self._memory.hit(bucket, limit, window_s)

    def test(self, bucket: str, limit: int, window_s: float) -> float | None:
        """Whether a hit would be admitted; asks memory for a few seconds when Redis fails."""
        if limit > 0 and time.monotonic() >= self._fallback_until:
            try:
                return self._window.test(bucket, limit, window_s)
            except redis.RedisError as exc:
                self._fall_back(exc)
        return self._memory.test(bucket, limit, window_s)

    def close(self) -> None:
        """Close the Redis connections."""
        self._storage.storage.close()

    def quota(self, settings: Settings, client: str, key_id: str | None) -> Quota:
        """The limits of a request by ``client`` with the key ``key_id`` (``None``: no key)."""
        return Quota(self, settings, client, key_id)


@dataclass(frozen=True)
class _Bucket:
    name: str
    limit: int
    scope: str


@dataclass(frozen=True)
class Refusal:
    """Why a window refused a request, and when it admits the next one (whole seconds)."""

    message: str
    retry_after: int

    @property
    def headers(self) -> dict[str, str]:
        """The headers of the 429 answer."""
        return {"Retry-After": str(self.retry_after)}


class Quota:
    """The rate limits one request is charged against: its client's, and its API key's."""

    def __init__(
        self, limiter: RateLimiter, settings: Settings, client: str, key_id: str | None
    ) -> None:
        self._limiter = limiter
        self._settings = settings
        self._client = client
        self._key_id = key_id

    def _limit(self, kind: Kind) -> int:
        settings = self._settings
        if kind == "read":
            return settings.rate_read_per_window
        if kind == "submit":
            return settings.rate_submit_per_window
        # Refusals are bounded while submissions are: no submit limit, no rejected limit.
        return settings.rate_rejected_per_window if settings.rate_submit_per_window > 0 else 0

    def _buckets(self, kind: Kind) -> list[_Bucket]:
        """Key bucket first (when a key's share is below the client's limit), then client."""
        limit = self._limit(kind)
        if limit <= 0:
            return []
        buckets = []
        share = self._settings.rate_key_share
        if self._key_id is not None and share < 1:
            key_limit = max(1, math.floor(limit * share))
            buckets.append(_Bucket(f"{kind}:key:{self._key_id}", key_limit, " with this API key"))
        buckets.append(_Bucket(f"{kind}:client:{quote(self._client, safe='')}", limit, ""))
        return buckets

    def _refusal(self, kind: Kind, bucket: _Bucket, retry_after: float) -> Refusal:
        window = f"{window_seconds(self._settings.rate_window_s)} s"
        what = "rejected submissions" if kind == "rejected" else f"{kind} requests"
        return Refusal(
            f"too many {what}{bucket.scope}: at most {bucket.limit} per {window}",
            max(1, math.ceil(retry_after)),
        )

    def limits(self, kind: Kind) -> bool:
        """Whether any window counts requests of ``kind`` (False: charging it does nothing)."""
        return self._limit(kind) > 0

    def charge(self, kind: Kind) -> Refusal | None:
        """Use one unit of ``kind`` in the key's and the client's windows; the refusal if one
        is full. A hit the client's window refuses after the key's admitted it keeps the key's
        unit (``limits`` windows have no refund); submissions test both windows first."""
        window_s = self._settings.rate_window_s
        for bucket in self._buckets(kind):
            retry_after = self._limiter.hit(bucket.name, bucket.limit, window_s)
            if retry_after is not None:
                return self._refusal(kind, bucket, retry_after)
        return None

    def check(self, kind: Kind) -> Refusal | None:
        """The refusal if the key's or the client's window of ``kind`` is full; uses nothing."""
        window_s = self._settings.rate_window_s
        for bucket in self._buckets(kind):
            retry_after = self._limiter.test(bucket.name, bucket.limit, window_s)
            if retry_after is not None:
                return self._refusal(kind, bucket, retry_after)
        return None

    def submitter(self) -> Submitter:
        """The client's name carrying this quota, as the submit use case receives it."""
        return Submitter(self._client, self)

    def note_rejected(self) -> None:
        """Count a submission refused with a 4xx against the rejected quota (never refuses)."""
        window_s = self._settings.rate_window_s
        for bucket in self._buckets("rejected"):
            self._limiter.hit(bucket.name, bucket.limit, window_s)


class AuthFailures:
    """Failed authentications (401) per client address in a moving window: once the window is
    full, that address is answered 429 before its key is looked up, so guessing keys or
    hammering the key table costs the caller, not the database."""

    def __init__(self, limiter: RateLimiter, settings: Settings, address: str) -> None:
        self._limiter = limiter
        self._limit = settings.rate_auth_failures_per_window
        self._window_s = settings.rate_window_s
        self._bucket = f"auth-failures:address:{quote(address, safe='')}"

    @property
    def limited(self) -> bool:
        """Whether failed authentications are counted at all (0 disables)."""
        return self._limit > 0

    def refusal(self) -> Refusal | None:
        """The 429 to answer when the address used up its failures; uses nothing."""
        retry_after = self._limiter.test(self._bucket, self._limit, self._window_s)
        if retry_after is None:
            return None
        window = f"{window_seconds(self._window_s)} s"
        return Refusal(
            f"too many failed authentications from this address: at most {self._limit} per "
            f"{window}",
            max(1, math.ceil(retry_after)),
        )

    def note_failure(self) -> None:
        """Count one failed authentication (never refuses)."""
        self._limiter.hit(self._bucket, self._limit, self._window_s)


class Submitter(str):
    """A submitting client's name carrying the :class:`Quota` its submission is charged to.

    It is what the submit route receives as its owner, so the job use case can charge the
    submit quota at the moment it accepts a job (under the client's submission lock) and the
    rejected quota when it refuses one.
    """

    quota: Quota | None

    def __new__(cls, client: str, quota: Quota | None = None) -> Submitter:
        """The client name ``client`` with ``quota`` attached."""
        self = super().__new__(cls, client)
        self.quota = quota
        return self
