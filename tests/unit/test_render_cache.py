"""The per-process store of rendered plots (pure logic): renders once per key, one at a time,
drops the least recently used beyond its size."""

from __future__ import annotations

import threading
import time

from app.report.cache import RenderCache


def test_a_key_renders_once_and_the_oldest_is_dropped_beyond_the_size() -> None:
    cache = RenderCache(max_bytes=10)
    assert cache.get("a", lambda: b"aaaa") == b"aaaa"
    assert cache.get("a", lambda: b"never") == b"aaaa"
    cache.get("b", lambda: b"bbbb")
    cache.get("a", lambda: b"never")  # a is now the most recent
    cache.get("c", lambda: b"cccc")  # 12 bytes: b, the least recent, goes
    assert cache.get("b", lambda: b"BBBB") == b"BBBB"
    assert cache.renders == 4


def test_concurrent_requests_of_one_plot_render_it_once_and_renders_never_overlap() -> None:
    cache = RenderCache()
    running = []
    overlaps = []

    def render() -> bytes:
        running.append(1)
        if len(running) > 1:
            overlaps.append(1)
        time.sleep(0.02)
        running.pop()
        return b"plot"

    threads = [
        threading.Thread(target=cache.get, args=(key, render)) for key in ("x", "x", "y", "x")
    ]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert cache.renders == 2 and overlaps == []
