"""bench.load_faults' own judgement of a stranded job: queued, and due but unsent, or sent with
no message waiting or freshly delivered; and how long each stayed so across samples."""

from __future__ import annotations

from bench.stranded import StrandMonitor, stranded_reason


def test_a_queued_job_is_stranded_only_when_nothing_will_run_it() -> None:
    assert stranded_reason(-3.0, None, 20.0) is None  # a sender holds it
    assert "unsent" in str(stranded_reason(4.0, None, 20.0))
    assert stranded_reason(None, ("waiting", 0.0), 20.0) is None
    assert stranded_reason(None, ("delivered", 5.0), 20.0) is None  # a worker is claiming it
    assert "never claimed" in str(stranded_reason(None, ("delivered", 45.0), 20.0))
    assert "no message" in str(stranded_reason(None, None, 20.0))


def test_the_monitor_keeps_the_longest_stranding_and_why() -> None:
    monitor = StrandMonitor("unused", "unused", "q", lease_s=10.0, bound_s=30.0)
    monitor._sample([("a", None), ("b", None)], {"b": ("waiting", 0.0)}, now=0.0)
    monitor._sample([("a", None), ("b", None)], {}, now=20.0)
    assert monitor.max_stranded_s == 20.0 and monitor.over_bound == {}
    monitor._sample([("a", None), ("b", None)], {}, now=40.0)
    assert monitor.max_stranded_s == 40.0
    assert list(monitor.over_bound) == ["a"] and "no message" in monitor.over_bound["a"]
    monitor._sample([("b", None)], {}, now=41.0)  # a ran; b stranded since 20 s
    assert monitor.max_stranded_s == 40.0
