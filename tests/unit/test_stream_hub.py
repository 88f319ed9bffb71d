"""The stream hub on a real SQLite database: caps, one watcher fanning out to every stream, the
event semantics each stream keeps, and a query count that does not grow with the streams."""

from __future__ import annotations

import asyncio
import json
import time
import uuid
from collections.abc import AsyncIterator, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import event, update

from app.errors import ApiError
from app.events import PollingWaker
from app.storage.models import Base, Job, utcnow
from app.storage.session import Database, create_db_engine
from app.stream_hub import STREAM_RETRY_AFTER_S, StreamHub, StreamSlots

OWNER = "team-a"


@pytest.fixture
def database(tmp_path: Path) -> Iterator[Database]:
    """A fresh SQLite database with the service's tables."""
    engine = create_db_engine(f"sqlite:///{tmp_path / 'hub.sqlite3'}")
    Base.metadata.create_all(engine)
    yield Database.for_engine(engine)
    engine.dispose()


def add_running_job(database: Database) -> str:
    """Insert a running job of :data:`OWNER` with no history yet."""
    job_id = str(uuid.uuid4())
    now = utcnow()
    with database.session() as session:
        session.add(
            Job(
                id=job_id,
                owner=OWNER,
                status="running",
                method="energy-scp",
                problem={},
                attempts=1,
                cancel_requested=False,
                created_at=now,
                updated_at=now,
                history=[],
            )
        )
    return job_id


def change(database: Database, job_id: str, **values: Any) -> None:
    """Update the job's row as a worker does (``updated_at`` moves on)."""
    with database.session() as session:
        session.execute(update(Job).where(Job.id == job_id).values(updated_at=utcnow(), **values))


def end_payload(job: Job) -> dict[str, Any]:
    """A small stand-in of the job view (the hub only encodes what it is given)."""
    return {"id": job.id, "status": job.status}


@dataclass
class Event:
    """One parsed server-sent event."""

    event: str | None
    id: str | None
    data: str


def parse(chunk: bytes) -> list[Event]:
    """The events of one written chunk (the wire format: fields, a blank line after each)."""
    events = []
    for block in chunk.decode("utf-8").split("\r\n\r\n"):
        if block:
            fields = dict(line.split(": ", 1) for line in block.split("\r\n"))
            events.append(Event(fields.get("event"), fields.get("id"), fields["data"]))
    return events


async def collect(stream: AsyncIterator[bytes], into: list[Event]) -> None:
    """Append every event of ``stream`` to ``into`` until it ends."""
    async for chunk in stream:
        into.extend(parse(chunk))


def summary(events: list[Event]) -> list[tuple[str | None, str | None, Any]]:
    """(event, id, data) of each event, data decoded."""
    return [(e.event, e.id, json.loads(e.data)) for e in events]


def test_slots_cap_each_client_and_the_total_and_come_back_when_released() -> None:
    slots = StreamSlots(max_total=3, max_per_client=2)
    a1, a2 = slots.acquire("a"), slots.acquire("a")
    with pytest.raises(ApiError) as refused:
        slots.acquire("a")
    error = refused.value
    assert (error.status, error.code) == (429, "too_many_streams")
    assert error.headers == {"Retry-After": str(STREAM_RETRY_AFTER_S)}
    assert "2 event streams open, at most 2 (TRAJOPT_MAX_STREAMS_PER_CLIENT)" in error.message
    slots.acquire("b")
    with pytest.raises(ApiError) as full:
        slots.acquire("c")
    assert "3 event streams open, at most 3 (TRAJOPT_MAX_STREAMS)" in full.value.message
    a1.release()
    a1.release()  # idempotent: the second call frees nothing more
    assert slots.open_count() == 2 and slots.open_count("a") == 1
    slots.acquire("c")
    a2.release()
    assert slots.open_count("a") == 0


def test_every_stream_gets_iterations_phases_and_the_end_from_one_watcher(
    database: Database,
) -> None:
    job_id = add_running_job(database)

    async def run() -> tuple[list[list[Event]], int]:
        hub = StreamHub(database, PollingWaker(0.02), max_streams=10, max_streams_per_client=10)
        streams: list[list[Event]] = [[], [], []]
        afters = [0, 0, 2]  # the third resumes with Last-Event-ID: 2
        tasks = [
            asyncio.create_task(
                collect(
                    hub.events(
                        job_id,
                        slot=hub.admit(OWNER),
                        end_payload=end_payload,
                        after=after,
                    ),
                    into,
                )
            )
            for after, into in zip(afters, streams, strict=True)
        ]
        await asyncio.sleep(0.2)
        change(database, job_id, progress={"phase": "optimizing", "elapsed_s": 0.5})
        await asyncio.sleep(0.2)
        history = [{"iteration": n, "cost": 10.0 - n} for n in (1, 2, 3)]
        change(database, job_id, history=history)
        await asyncio.sleep(0.2)
        # a new attempt starts its history again
        change(database, job_id, attempts=2, history=history[:1], progress={"phase": "optimizing"})
        await asyncio.sleep(0.2)
        change(database, job_id, status="succeeded", progress={"phase": "verifying"})
        await asyncio.wait_for(asyncio.gather(*tasks), 5)
        open_after = hub.slots.open_count()
        await hub.close()
        return streams, open_after

    streams, open_after = asyncio.run(run())
    assert open_after == 0  # each stream gave its slot back when it ended
    first = summary(streams[0])
    assert first == summary(streams[1])
    assert first == [
        ("phase", None, {"job_id": job_id, "attempt": 1, "phase": "optimizing", "elapsed_s": 0.5}),
        *[
            (
                "iteration",
                str(n),
                {"job_id": job_id, "attempt": 1, "iteration": n, "cost": 10.0 - n},
            )
            for n in (1, 2, 3)
        ],
        ("iteration", "1", {"job_id": job_id, "attempt": 2, "iteration": 1, "cost": 9.0}),
        ("phase", None, {"job_id": job_id, "attempt": 2, "phase": "optimizing", "elapsed_s": None}),
        ("end", "2", {"id": job_id, "status": "succeeded"}),
    ]
    resumed = summary(streams[2])
    assert [(kind, ident) for kind, ident, _ in resumed] == [
        ("phase", None),
        ("iteration", "3"),
        ("iteration", "1"),
        ("phase", None),
        ("end", "2"),
    ]


def test_a_notice_wakes_the_streams_long_before_the_poll(database: Database) -> None:
    job_id = add_running_job(database)

    async def run() -> float:
        waker = PollingWaker(interval_s=5.0)
        hub = StreamHub(database, waker, max_streams=10, max_streams_per_client=10)
        events: list[Event] = []
        task = asyncio.create_task(
            collect(hub.events(job_id, slot=hub.admit(OWNER), end_payload=end_payload), events)
        )
        await asyncio.sleep(0.2)
        change(database, job_id, status="failed")
        start = time.perf_counter()
        waker.notify("other-job")  # another job's notice changes nothing here
        await asyncio.to_thread(waker.notify, job_id)  # from another thread, as the pool does
        await asyncio.wait_for(task, 5)
        await hub.close()
        assert [e.event for e in events] == ["end"]
        return time.perf_counter() - start

    # the notice ends the stream at once, far below the 5 s poll; 1 s absorbs a busy machine
    assert asyncio.run(run()) < 1.0


def test_an_ended_attempt_is_read_at_once_after_a_burst_of_iterations(
    database: Database,
) -> None:
    """Iteration notices drain the read bucket (3 back to back, then one per gap); the notice
    that the attempt ended is read at once, not a gap later. A 2 s gap makes the difference
    plain: paced, the end would wait about 2 s; 1 s absorbs a busy machine."""
    job_id = add_running_job(database)

    async def run() -> tuple[float, int]:
        waker = PollingWaker(interval_s=30.0)
        hub = StreamHub(
            database, waker, max_streams=10, max_streams_per_client=10, min_read_gap_s=2.0
        )
        events: list[Event] = []
        task = asyncio.create_task(
            collect(hub.events(job_id, slot=hub.admit(OWNER), end_payload=end_payload), events)
        )
        await asyncio.sleep(0.1)
        for n in range(1, 4):  # each iteration notice spends a read
            change(database, job_id, history=[{"iteration": i} for i in range(1, n + 1)])
            hub._on_notice(job_id)
            await asyncio.sleep(0.05)
        change(database, job_id, status="failed")
        start = time.perf_counter()
        hub._on_notice(job_id, True)
        await asyncio.wait_for(task, 10)
        elapsed = time.perf_counter() - start
        await hub.close()
        assert events[-1].event == "end"
        return elapsed, hub.reads

    elapsed, reads = asyncio.run(run())
    assert elapsed < 1.0, elapsed
    assert reads >= 4  # the first read and the three iterations' reads did happen


def count_queries(database: Database, streams: int, seconds: float) -> tuple[int, int]:
    """SQL statements and hub reads in ``seconds`` while ``streams`` streams watch one idle
    running job (polling every 50 ms, the embedded default: the worst case)."""
    job_id = add_running_job(database)
    statements = 0

    def count(*_: Any) -> None:
        nonlocal statements
        statements += 1

    async def run() -> tuple[int, int]:
        nonlocal statements
        hub = StreamHub(
            database,
            PollingWaker(0.05),
            max_streams=streams,
            max_streams_per_client=streams,
            min_read_gap_s=0.05,
        )
        sinks: list[list[Event]] = [[] for _ in range(streams)]
        tasks = [
            asyncio.create_task(
                collect(hub.events(job_id, slot=hub.admit(OWNER), end_payload=end_payload), sink)
            )
            for sink in sinks
        ]
        await asyncio.sleep(0.3)  # every stream is open and has had its first frame
        statements, reads = 0, hub.reads
        await asyncio.sleep(seconds)
        counted = statements, hub.reads - reads
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        assert hub.slots.open_count() == 0 and hub.watched() == 0
        await hub.close()
        return counted

    event.listen(database.engine, "before_cursor_execute", count)
    try:
        return asyncio.run(run())
    finally:
        event.remove(database.engine, "before_cursor_execute", count)


def test_database_queries_do_not_grow_with_the_number_of_streams(database: Database) -> None:
    one, one_reads = count_queries(database, 1, 1.0)
    many, many_reads = count_queries(database, 300, 1.0)
    # One poll per 50 ms: at most 20 reads per second, each a single query while the job is
    # idle, whether 1 or 300 streams watch it (the old per-stream loop made 300 x 20 = 6000).
    # Slack of 2 for the timing of the first and last poll of the window.
    assert 5 <= one <= 22 and 5 <= many <= 22, (one, many)
    assert one_reads == one and many_reads == many  # an idle job: no full-row reads
