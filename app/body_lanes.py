"""One lane per client for large request bodies, so that one client cannot take the API's CPU.

Reading and decoding a body of a megabyte costs milliseconds of CPU under the interpreter lock,
and every other request of the process waits for that lock. A client posting such bodies on
several connections without pause would hold it most of the time, and every other client's
reads would slow down with it (measured: a read's p95 went from 6 to 31 ms under two such
connections on two cores). Through its lane, a client's large bodies are read and decoded one
at a time, and after each one the lane stays closed for long enough that the client's large
bodies take at most :data:`LARGE_BODY_SHARE` of the process's time: its waiting requests sleep
(costing nothing) and every other client keeps the rest. A valid problem is a few kilobytes,
far below :data:`LARGE_BODY_BYTES`, and never waits.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

LARGE_BODY_BYTES = 65_536
"""Bodies above this size (or of unknown size: chunked) go through their client's lane."""
LARGE_BODY_SHARE = 0.25
"""The largest share of the process's time one client's large bodies may take."""
_PRUNE_AT = 64
"""Forget the cool-downs of idle clients once this many are remembered."""


class BodyLanes:
    """Per client: a lock for its large bodies, and when its cool-down ends.

    Used on the event loop only (no thread touches it), so the bookkeeping needs no lock of its
    own.
    """

    def __init__(self, share: float = LARGE_BODY_SHARE) -> None:
        if not 0 < share <= 1:
            raise ValueError(f"share must be in (0, 1], got {share}")
        self.share = share
        self._locks: dict[str, asyncio.Lock] = {}
        self._users: dict[str, int] = {}
        self._ready_at: dict[str, float] = {}

    @asynccontextmanager
    async def lane(self, client: str) -> AsyncIterator[None]:
        """Hold ``client``'s lane for the block: one large body of that client at a time, once
        the cool-down of its previous one has passed."""
        lock = self._locks.setdefault(client, asyncio.Lock())
        self._users[client] = self._users.get(client, 0) + 1
        try:
            async with lock:
                wait = self._ready_at.get(client, 0.0) - time.monotonic()
                if wait > 0:
                    await asyncio.sleep(wait)
                started = time.monotonic()
                try:
                    yield
                finally:
                    ended = time.monotonic()
                    self._ready_at[client] = ended + (ended - started) * (1 / self.share - 1)
        finally:
            self._users[client] -= 1
            if self._users[client] == 0:
                del self._users[client]
                del self._locks[client]
            if len(self._ready_at) > _PRUNE_AT:
                self._prune(time.monotonic())

    def _prune(self, now: float) -> None:
        """Drop the cool-downs that have passed, of clients with nothing in flight."""
        for client in [c for c, t in self._ready_at.items() if t <= now and c not in self._users]:
            del self._ready_at[client]

    def clients(self) -> int:
        """How many clients have a large body in flight or waiting."""
        return len(self._locks)


def is_large(content_length: str | None) -> bool:
    """Whether a body declared with this ``Content-Length`` header (None: chunked) is large."""
    if content_length is None:
        return True
    try:
        return int(content_length) > LARGE_BODY_BYTES
    except ValueError:
        return True
