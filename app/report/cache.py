"""Rendered plots kept per process: a finished job's result never changes, so its plots are
rendered once; and one render at a time, so a page asking for eight plots takes one core, not
every thread the server has."""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable

MAX_BYTES = 32 * 1024 * 1024
"""What the kept plots may take in all (a plot is 20-120 kB)."""


class RenderCache:
    """A least-recently-used store of rendered bytes by key, rendering under one lock."""

    def __init__(self, max_bytes: int = MAX_BYTES) -> None:
        self.max_bytes = max_bytes
        self._kept: OrderedDict[Hashable, bytes] = OrderedDict()
        self._size = 0
        self._lock = threading.Lock()
        self._render_lock = threading.Lock()
        self.renders = 0

    def get(self, key: Hashable, render: Callable[[], bytes]) -> bytes:
        """The bytes kept for ``key``, else ``render()``'s (kept for next time)."""
        with self._lock:
            found = self._kept.get(key)
            if found is not None:
                self._kept.move_to_end(key)
                return found
        with self._render_lock:  # one render at a time; a concurrent twin renders once
            with self._lock:
                found = self._kept.get(key)
            if found is not None:
                return found
            made = render()
            self.renders += 1
        with self._lock:
            if key not in self._kept:
                self._kept[key] = made
                self._size += len(made)
            while self._size > self.max_bytes and self._kept:
                _, dropped = self._kept.popitem(last=False)
                self._size -= len(dropped)
        return made
