"""Event-stream helpers: resuming from ``Last-Event-ID`` and waking streams early."""

from __future__ import annotations

import asyncio
import threading
import time

from app.events import PollingWaker, parse_last_event_id


def test_last_event_id_parsing() -> None:
    assert parse_last_event_id(None) == 0
    assert parse_last_event_id(" 7 ") == 7
    assert parse_last_event_id("-3") == 0
    assert parse_last_event_id("end") == 0


def test_polling_waker_sleeps_the_interval_without_a_notice() -> None:
    async def run() -> float:
        waker = PollingWaker(interval_s=0.05)
        async with waker.subscribe("job") as wait:
            start = time.perf_counter()
            await wait(10.0)
            return time.perf_counter() - start

    elapsed = asyncio.run(run())
    # the interval bounds the wait; 0.04 s of slack absorbs scheduling on a busy machine
    assert 0.045 <= elapsed < 0.09


def test_polling_waker_wakes_at_once_on_a_notice_from_another_thread() -> None:
    async def run() -> float:
        waker = PollingWaker(interval_s=5.0)
        async with waker.subscribe("job") as wait:
            threading.Timer(0.05, waker.notify, args=("job",)).start()
            waker.notify("other-job")  # other jobs' notices do not wake this stream
            start = time.perf_counter()
            await wait(10.0)
            return time.perf_counter() - start

    elapsed = asyncio.run(run())
    # woken by the notice after 0.05 s, far below the 5 s interval; 1 s is generous slack
    assert 0.04 <= elapsed < 1.0
