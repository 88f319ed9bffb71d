"""The warm-up tells its caller when it is compiling (still running after NOTICE_AFTER_S), and
stays silent when the kernels load from the cache or are loaded already."""

from __future__ import annotations

import time

import pytest

from worker.solver import warmup


def test_a_slow_warm_up_calls_the_notice_once(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(warmup, "_warmed", False)
    monkeypatch.setattr(warmup, "NOTICE_AFTER_S", 0.05)
    monkeypatch.setattr(warmup, "_load_kernels", lambda: time.sleep(0.3) or 0.3)
    heard: list[str] = []
    warmup.warm_up(lambda: heard.append("compiling"))
    assert heard == ["compiling"]


def test_a_fast_warm_up_stays_silent(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(warmup, "_warmed", False)
    monkeypatch.setattr(warmup, "NOTICE_AFTER_S", 0.2)
    monkeypatch.setattr(warmup, "_load_kernels", lambda: 0.0)
    heard: list[str] = []
    warmup.warm_up(lambda: heard.append("compiling"))
    time.sleep(0.3)  # a timer that was not cancelled would have fired by now
    assert heard == []


def test_loaded_kernels_return_at_once_without_notice(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(warmup, "_warmed", True)
    monkeypatch.setattr(warmup, "NOTICE_AFTER_S", 0.0)
    heard: list[str] = []
    assert warmup.warm_up(lambda: heard.append("compiling")) == 0.0
    time.sleep(0.05)
    assert heard == []
