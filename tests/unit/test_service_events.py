"""Event-stream helpers: resuming from ``Last-Event-ID`` and the waker's notices."""

from __future__ import annotations

import asyncio
import threading

from app.events import PollingWaker, parse_last_event_id


def test_last_event_id_parsing() -> None:
    assert parse_last_event_id(None) == 0
    assert parse_last_event_id(" 7 ") == 7
    assert parse_last_event_id("-3") == 0
    assert parse_last_event_id("end") == 0


def test_polling_waker_reports_its_interval() -> None:
    assert PollingWaker(interval_s=0.05).poll_interval() == 0.05


def test_polling_waker_delivers_a_notice_from_another_thread_on_the_loop() -> None:
    async def run() -> tuple[list[str | None], bool]:
        waker = PollingWaker(interval_s=5.0)
        waker.notify("before-start")  # no watcher yet: dropped, not raised
        got: list[str | None] = []
        on_loop: list[bool] = []
        loop = asyncio.get_running_loop()
        arrived = asyncio.Event()

        def on_notice(job_id: str | None, ended: bool) -> None:
            assert ended  # the local pool's notice: the job is done
            got.append(job_id)
            on_loop.append(asyncio.get_running_loop() is loop)
            arrived.set()

        await waker.start(on_notice)
        threading.Timer(0.05, waker.notify, args=("job",)).start()
        await asyncio.wait_for(arrived.wait(), 2.0)
        await waker.close()
        waker.notify("after-close")  # dropped too
        await asyncio.sleep(0.05)
        return got, all(on_loop)

    got, on_loop = asyncio.run(run())
    assert got == ["job"] and on_loop
