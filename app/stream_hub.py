"""The event streams of one API process: caps on how many are open, and one shared watcher.

Streams cost no database reads of their own. One watcher task per process reads the rows of the
jobs a notice named in one query (every watched job's, in two, once per poll interval: their
heads first, then only the changed rows; never their problem or result documents), turns it into
a :class:`JobFrame` (each iteration's event data encoded once) and wakes every stream of that job;
each stream only keeps its own cursor (iterations sent, attempt, phase). Reads are paced by a
bucket of ``READ_BURST`` reads refilled one per ``min_read_gap_s``: at most ``READ_BURST`` +
t / ``min_read_gap_s`` reads in any t seconds, so a process makes a bounded number of queries per
second however many streams and jobs it serves. A notice that a job's attempt ended is read at
once whatever the bucket holds (one per attempt, so the bound grows by the attempts that end):
the last iterations of a job drain the bucket, and its ``end`` would otherwise wait a gap.

The caps are per process: ``max_streams`` in all and ``max_streams_per_client`` per client. A
stream over either cap is refused with 429 ``too_many_streams`` before it opens.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import json
import logging
import threading
import time
from collections.abc import AsyncIterator, Callable, Iterable
from dataclasses import dataclass
from datetime import datetime
from typing import Any

import anyio.to_thread
from sqlalchemy import select
from sqlalchemy.orm import defer
from sse_starlette.sse import ServerSentEvent

from app.errors import ApiError
from app.events import Waker
from app.storage.models import TERMINAL_STATUSES, Job
from app.storage.session import Database

log = logging.getLogger(__name__)

READ_BURST = 3.0
"""Reads the watcher may make back to back before the minimum gap paces it (see the module)."""

STREAM_RETRY_AFTER_S = 5
"""Retry-After of a refused stream: streams last as long as jobs run, so a few seconds."""

Head = tuple[str, datetime]
"""A job row's (status, updated_at): it changed when either differs."""


class StreamSlots:
    """Counts the open streams of this process, in all and per client (thread-safe)."""

    def __init__(self, max_total: int, max_per_client: int) -> None:
        self.max_total = max_total
        self.max_per_client = max_per_client
        self._lock = threading.Lock()
        self._total = 0
        self._per_client: dict[str, int] = {}

    def acquire(self, client: str) -> StreamSlot:
        """A slot for one more stream of ``client``, or 429 ``too_many_streams``."""
        with self._lock:
            mine = self._per_client.get(client, 0)
            if mine >= self.max_per_client:
                raise _refusal(
                    f"this client has {mine} event streams open, at most {self.max_per_client} "
                    "(TRAJOPT_MAX_STREAMS_PER_CLIENT); close one"
                )
            if self._total >= self.max_total:
                raise _refusal(
                    f"the server has {self._total} event streams open, at most {self.max_total} "
                    "(TRAJOPT_MAX_STREAMS)"
                )
            self._total += 1
            self._per_client[client] = mine + 1
        return StreamSlot(self, client)

    def _release(self, client: str) -> None:
        with self._lock:
            self._total -= 1
            left = self._per_client.get(client, 1) - 1
            if left > 0:
                self._per_client[client] = left
            else:
                self._per_client.pop(client, None)

    def open_count(self, client: str | None = None) -> int:
        """Streams open now, in all or of ``client``."""
        with self._lock:
            return self._total if client is None else self._per_client.get(client, 0)


def _refusal(reason: str) -> ApiError:
    return ApiError(
        429,
        "too_many_streams",
        f"too many event streams: {reason}, or retry after {STREAM_RETRY_AFTER_S} s",
        headers={"Retry-After": str(STREAM_RETRY_AFTER_S)},
    )


class StreamSlot:
    """One admitted stream; :meth:`release` (idempotent) frees its place."""

    def __init__(self, slots: StreamSlots, client: str) -> None:
        self._slots = slots
        self._client = client
        self._released = False
        self._lock = threading.Lock()

    def release(self) -> None:
        """Give the place back (once, however often it is called)."""
        with self._lock:
            if self._released:
                return
            self._released = True
        self._slots._release(self._client)


@dataclass(frozen=True)
class JobFrame:
    """What every stream of a job needs from one read of its row."""

    version: int
    job: Job | None
    """The row as read (``None``: the job is gone)."""
    attempt: int
    iterations: tuple[bytes, ...]
    """Each iteration event of the current attempt as sent (id: its number), encoded once."""
    phase: tuple[int, str] | None
    phase_event: bytes | None

    @property
    def terminal(self) -> bool:
        """Whether the job has ended (no event follows ``end``)."""
        return self.job is not None and self.job.status in TERMINAL_STATUSES


def _phase_of(job: Job) -> tuple[int, str] | None:
    """The running attempt's phase as (attempt, phase), if its progress names one."""
    progress = job.progress if isinstance(job.progress, dict) else {}
    name = progress.get("phase")
    return (job.attempts, name) if isinstance(name, str) else None


class _Watch:
    """The latest frame of one watched job and the event its streams wait on."""

    def __init__(self, job_id: str) -> None:
        self.job_id = job_id
        self.streams = 0
        self.head: Head | None = None
        self.frame: JobFrame | None = None
        self.changed = asyncio.Event()
        self._end: tuple[int, str] | None = None

    def publish(self, job: Job | None) -> None:
        """Turn a fresh read of the row into the next frame and wake the streams."""
        version = self.frame.version + 1 if self.frame is not None else 1
        if job is None:
            frame = JobFrame(version, None, 0, (), None, None)
        else:
            self.head = (job.status, job.updated_at)
            history = list(job.history or [])
            previous = self.frame
            if (
                previous is not None
                and previous.attempt == job.attempts
                and len(history) >= len(previous.iterations)
            ):
                encoded = previous.iterations + self._encode(job, history, len(previous.iterations))
            else:
                encoded = self._encode(job, history, 0)
            phase = _phase_of(job)
            phase_event = None
            if phase is not None and job.status not in TERMINAL_STATUSES:
                data = {"job_id": self.job_id, "attempt": phase[0], "phase": phase[1]}
                data["elapsed_s"] = (job.progress or {}).get("elapsed_s")
                phase_event = ServerSentEvent(data=json.dumps(data), event="phase").encode()
            frame = JobFrame(version, job, job.attempts, encoded, phase, phase_event)
        self.frame = frame
        woken, self.changed = self.changed, asyncio.Event()
        woken.set()

    def _encode(self, job: Job, history: list[Any], start: int) -> tuple[bytes, ...]:
        return tuple(
            ServerSentEvent(
                data=json.dumps({"job_id": self.job_id, "attempt": job.attempts, **history[index]}),
                event="iteration",
                id=str(index + 1),
            ).encode()
            for index in range(start, len(history))
        )

    def end_event(self, frame: JobFrame, end_payload: Callable[[Job], Any], ident: int) -> bytes:
        """The ``end`` event of a terminal frame with id ``ident``; its data made once."""
        if self._end is None or self._end[0] != frame.version:
            assert frame.job is not None
            self._end = (frame.version, json.dumps(end_payload(frame.job)))
        return ServerSentEvent(data=self._end[1], event="end", id=str(ident)).encode()


_LIGHT = (defer(Job.problem, raiseload=True), defer(Job.result, raiseload=True))
"""A stream needs neither the problem nor the result document: they are not read."""


def read_changed(
    database: Database, known: dict[str, Head | None], *, likely_changed: bool = False
) -> dict[str, Job | None]:
    """The rows of the jobs in ``known`` whose (status, updated_at) differ from what is known,
    and ``None`` for those that are gone: two queries, whatever the number of jobs.

    With ``likely_changed`` (each job was named by a notice) the rows are read in one query
    and those unchanged dropped here: a notice almost always follows a write.
    """
    ids = list(known)
    with database.reader() as session:
        if likely_changed:
            rows = session.execute(select(Job).options(*_LIGHT).where(Job.id.in_(ids))).scalars()
            found = {job.id: job for job in rows}
            out: dict[str, Job | None] = {job_id: None for job_id in ids if job_id not in found}
            for job_id, job in found.items():
                if (job.status, job.updated_at) != known.get(job_id):
                    out[job_id] = job
            return out
        heads = {
            job_id: (status, updated_at)
            for job_id, status, updated_at in session.execute(
                select(Job.id, Job.status, Job.updated_at).where(Job.id.in_(ids))
            )
        }
        out = {job_id: None for job_id in ids if job_id not in heads}
        changed = [job_id for job_id, head in heads.items() if head != known.get(job_id)]
        if changed:
            query = select(Job).options(*_LIGHT).where(Job.id.in_(changed))
            for job in session.execute(query).scalars():
                out[job.id] = job
        return out


class StreamHub:
    """Admits streams under the caps and feeds them all from one watcher task."""

    def __init__(
        self,
        database: Database,
        waker: Waker,
        *,
        max_streams: int,
        max_streams_per_client: int,
        min_read_gap_s: float = 0.05,
    ) -> None:
        self.slots = StreamSlots(max_streams, max_streams_per_client)
        self.reads = 0
        """Row reads (each two queries at most) since start; for tests and operators."""
        self._database = database
        self._waker = waker
        self._min_gap = min_read_gap_s
        self._tokens = READ_BURST
        self._refilled = time.monotonic()
        self._watches: dict[str, _Watch] = {}
        self._dirty: set[str] = set()
        self._all_dirty = False
        self._wake = asyncio.Event()
        self._ended = asyncio.Event()
        self._task: asyncio.Task[None] | None = None
        self._failing = False

    def admit(self, client: str) -> StreamSlot:
        """A place for one more stream of ``client`` (429 ``too_many_streams`` if none)."""
        return self.slots.acquire(client)

    async def events(
        self,
        job_id: str,
        *,
        slot: StreamSlot,
        end_payload: Callable[[Job], Any],
        after: int = 0,
    ) -> AsyncIterator[bytes]:
        """Stream the job's iterations from number ``after + 1`` on, a ``phase`` event when the
        attempt's phase changes, then one ``end`` event; ``slot`` is released at the end.

        Each item is every event that is new to this stream, encoded (one write per change).
        ``end_payload`` turns the finished job's row into the data of the ``end`` event.
        """
        try:
            watch = await self._watch(job_id)
            try:
                async for event in _follow(watch, end_payload, after):
                    yield event
            finally:
                self._unwatch(watch)
        finally:
            slot.release()

    async def _watch(self, job_id: str) -> _Watch:
        watch = self._watches.get(job_id)
        if watch is None:
            watch = self._watches[job_id] = _Watch(job_id)
            self._dirty.add(job_id)
            self._wake.set()
        watch.streams += 1
        if self._task is None or self._task.done():
            await self._waker.start(self._on_notice)
            self._task = asyncio.create_task(self._run(), name="trajopt-stream-watcher")
        return watch

    def _unwatch(self, watch: _Watch) -> None:
        watch.streams -= 1
        if watch.streams <= 0 and self._watches.get(watch.job_id) is watch:
            del self._watches[watch.job_id]
            self._dirty.discard(watch.job_id)

    def _on_notice(self, job_id: str | None, ended: bool = False) -> None:
        if job_id is None:
            self._all_dirty = True
        elif job_id in self._watches:
            self._dirty.add(job_id)
            if ended:
                self._ended.set()
        else:
            return  # another process's stream, or none at all
        self._wake.set()

    def watched(self) -> int:
        """Jobs with at least one open stream in this process."""
        return len(self._watches)

    async def _run(self) -> None:
        last_full = time.monotonic()
        while True:
            if not self._watches:
                self._wake.clear()
                await self._wake.wait()
            interval = self._waker.poll_interval()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(
                    self._wake.wait(), max(0.0, interval - (time.monotonic() - last_full))
                )
            self._wake.clear()
            self._ended.clear()
            started = time.monotonic()
            full = self._all_dirty or started - last_full >= interval
            if full:
                due: Iterable[str] = list(self._watches)
                last_full = started
            else:  # only the jobs a notice named
                due = [job_id for job_id in self._dirty if job_id in self._watches]
            self._dirty.clear()
            self._all_dirty = False
            if due:
                await self._refresh(due, likely_changed=not full)
                with contextlib.suppress(TimeoutError):  # paced, unless an attempt ends
                    await asyncio.wait_for(self._ended.wait(), self._pace())

    def _pace(self) -> float:
        """Spend one read from the bucket; seconds to wait before the next read may start."""
        now = time.monotonic()
        refill = (now - self._refilled) / self._min_gap if self._min_gap > 0 else READ_BURST
        self._tokens = min(READ_BURST, self._tokens + refill) - 1.0
        self._refilled = now
        return max(0.0, -self._tokens * self._min_gap)

    async def _refresh(self, due: Iterable[str], likely_changed: bool = False) -> None:
        known = {job_id: self._watches[job_id].head for job_id in due if job_id in self._watches}
        read = functools.partial(read_changed, likely_changed=likely_changed)
        try:
            rows = await anyio.to_thread.run_sync(read, self._database, known)
        except Exception as exc:
            self._dirty.update(known)  # read them again at the next turn
            if not self._failing:
                self._failing = True
                log.warning("event streams cannot read their jobs (%s); retrying", exc)
            await asyncio.sleep(self._waker.poll_interval())
            return
        if self._failing:
            self._failing = False
            log.info("event streams read their jobs again")
        self.reads += 1
        for job_id, job in rows.items():
            watch = self._watches.get(job_id)
            if watch is not None:
                watch.publish(job)

    async def close(self) -> None:
        """Stop the watcher (the streams end with the server)."""
        task, self._task = self._task, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task


async def _follow(
    watch: _Watch, end_payload: Callable[[Job], Any], after: int
) -> AsyncIterator[bytes]:
    """One stream's cursor over the frames of its job."""
    sent = after
    attempt: int | None = None
    phase: tuple[int, str] | None = None
    seen = 0
    while True:
        changed, frame = watch.changed, watch.frame
        if frame is None or frame.version == seen:
            await changed.wait()
            continue
        seen = frame.version
        if frame.job is None:
            return
        if attempt is not None and frame.attempt != attempt:
            sent = 0  # a new attempt starts its history again
        attempt = frame.attempt
        out = list(frame.iterations[sent:])
        sent = max(sent, len(frame.iterations))
        if frame.phase_event is not None and frame.phase != phase:
            phase = frame.phase
            out.append(frame.phase_event)
        if frame.terminal:
            out.append(watch.end_event(frame, end_payload, sent + 1))
        if out:
            yield b"".join(out)
        if frame.terminal:
            return
