"""The per-process store of rendered plots (pure logic): what is kept is found, the least
recently used goes beyond the size."""

from __future__ import annotations

from app.report.cache import RenderCache


def test_the_least_recently_used_is_dropped_beyond_the_size() -> None:
    cache = RenderCache(max_bytes=10)
    cache.keep("a", b"aaaa")
    cache.keep("a", b"AAAA")  # kept once: a finished result's plot does not change
    assert cache.find("a") == b"aaaa"
    cache.keep("b", b"bbbb")
    assert cache.find("a") == b"aaaa"  # a is now the most recent
    cache.keep("c", b"cccc")  # 12 bytes: b, the least recent, goes
    assert cache.find("b") is None
    assert (cache.find("a"), cache.find("c")) == (b"aaaa", b"cccc")
