"""A failure that repeats is logged once with its traceback, then one line at growing
intervals counting the failures in between, then one line when it ends."""

from __future__ import annotations

import logging

import pytest

from app.failure_log import FailureLog


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_a_streak_of_failures_is_logged_with_back_off(caplog: pytest.LogCaptureFixture) -> None:
    clock = Clock()
    failures = FailureLog(logging.getLogger("t"), "job 1", clock=clock, longest_repeat_s=8.0)
    caplog.set_level(logging.INFO, logger="t")
    for _ in range(300):  # a failure every 0.1 s for 30 s
        failures.failed(ConnectionError("refused\nmore detail"), "store progress")
        clock.now += 0.1
    failures.succeeded()
    records = caplog.records
    assert records[0].exc_info is not None and "could not store progress" in records[0].message
    repeats = records[1:-1]
    assert all(r.exc_info is None and "still failing" in r.message for r in repeats)
    assert "more detail" not in repeats[0].message  # one line each
    # lines after 1, 2, 4, 8, 8 s ... : gaps double up to the cap
    assert len(repeats) == 5
    assert "after 300 failure(s) in 30 s" in records[-1].message
    assert failures.failures == 0


def test_a_new_kind_of_failure_is_logged_at_once(caplog: pytest.LogCaptureFixture) -> None:
    clock = Clock()
    failures = FailureLog(logging.getLogger("t"), "relay", clock=clock)
    caplog.set_level(logging.INFO, logger="t")
    failures.failed(ConnectionError("down"), "send")
    failures.failed(ConnectionError("down"), "send")
    failures.failed(TimeoutError("slow"), "send")
    assert [r.message.split(":")[1].strip()[:13] for r in caplog.records] == [
        "could not sen",
        "still failing",
    ]
    failures.succeeded()
    failures.succeeded()  # no streak: nothing more
    assert len(caplog.records) == 3
