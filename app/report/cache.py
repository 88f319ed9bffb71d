"""Rendered plots kept per process: a finished job's result never changes, so each of its plots
is rendered once (a batch's plot is kept under its children's state, so a changed batch is
rendered again)."""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Hashable

MAX_BYTES = 32 * 1024 * 1024
"""What the kept plots may take in all (a plot is 20-120 kB)."""


class RenderCache:
    """A least-recently-used store of rendered bytes by key, at most ``max_bytes`` in all."""

    def __init__(self, max_bytes: int = MAX_BYTES) -> None:
        self.max_bytes = max_bytes
        self._kept: OrderedDict[Hashable, bytes] = OrderedDict()
        self._size = 0
        self._lock = threading.Lock()

    def find(self, key: Hashable) -> bytes | None:
        """The bytes kept for ``key`` (now the most recently used), or None."""
        with self._lock:
            found = self._kept.get(key)
            if found is not None:
                self._kept.move_to_end(key)
            return found

    def keep(self, key: Hashable, made: bytes) -> None:
        """Keep ``made`` for ``key``, dropping the least recently used beyond the size."""
        with self._lock:
            if key in self._kept:
                return
            self._kept[key] = made
            self._size += len(made)
            while self._size > self.max_bytes and self._kept:
                _, dropped = self._kept.popitem(last=False)
                self._size -= len(dropped)
