"""Plots rendered in a pool of processes, one render of a client at a time, clients in turn.

matplotlib holds the interpreter lock while it draws (0.1-1 s a plot), so a plot rendered in a
thread of the API process slows every other request of that process. Renders run in separate
processes instead, and each client has a lane: at most one of its renders in progress, its
other requests waiting in its own queue. A free process takes the next render of the client
whose turn it is (round robin), so another client's plot waits at most for the renders already
in progress, however many one client asks for. A client's queue is bounded: past it, 429
``too_many_renders`` with a Retry-After. What was rendered is kept (:class:`RenderCache`), and
concurrent requests of one plot share one render.

The bookkeeping runs on the event loop only (no lock); a waiting request holds no thread.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import multiprocessing
import os
import signal
import threading
import time
from collections import deque
from collections.abc import Awaitable, Callable, Hashable
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from typing import Any

from app.errors import ApiError
from app.report.cache import RenderCache

log = logging.getLogger(__name__)

RENDER_RETRY_AFTER_S = 2
"""The Retry-After of a refused render (a render takes 0.1-1 s)."""
PARENT_WATCH_INTERVAL_S = 1.0
"""How often a render process checks that the server that started it is still alive."""
STOP_JOIN_TIMEOUT_S = 5.0
"""How long shutdown waits for each killed render process to be reaped."""


def _watch_parent(parent_pid: int) -> None:
    while True:
        time.sleep(PARENT_WATCH_INTERVAL_S)
        if os.getppid() != parent_pid:  # the server died (kill -9): do not run on as an orphan
            os._exit(1)


def _init_process(parent_pid: int) -> None:
    # Ctrl+C, or a SIGTERM to the whole process group, reaches these processes too; the server
    # stops them in its shutdown, and they exit by themselves if it dies
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True).start()


def _warm_up() -> None:
    """Import matplotlib and draw once (its fonts load on the first draw)."""
    from app.report.plots import render_plot

    render_plot({"history": [{"cost": 1.0}]}, "convergence", "png")


def _process_pool(processes: int) -> ProcessPoolExecutor:
    """``processes`` spawned render processes, each warming up at once."""
    pool = ProcessPoolExecutor(
        max_workers=processes,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_init_process,
        initargs=(os.getpid(),),
    )
    for _ in range(processes):
        pool.submit(_warm_up)
    return pool


@dataclass
class _Render:
    """One render waiting for a process, or in progress."""

    client: str
    key: Hashable
    function: Callable[..., bytes]
    args: tuple[Any, ...]
    done: asyncio.Future[bytes]


@dataclass
class _Lanes:
    """Per client: its renders not started, in order; the clients whose turn comes, in turn."""

    waiting: dict[str, deque[_Render]] = field(default_factory=dict)
    turns: deque[str] = field(default_factory=deque)
    busy: set[str] = field(default_factory=set)
    """Clients with a render in progress (not in ``turns`` until it ends)."""
    preparing: dict[str, int] = field(default_factory=dict)
    """Per client: renders whose arguments are being read."""

    def queued(self, client: str) -> int:
        """The client's renders being prepared, waiting or in progress."""
        mine = len(self.waiting.get(client, ())) + (client in self.busy)
        return mine + self.preparing.get(client, 0)

    def done_preparing(self, client: str) -> None:
        """One render of ``client`` has its arguments (or failed to get them)."""
        left = self.preparing[client] - 1
        if left:
            self.preparing[client] = left
        else:
            del self.preparing[client]


class RenderPool:
    """``processes`` render processes shared fairly between clients; each client may have
    ``queue_per_client`` renders waiting or in progress."""

    def __init__(
        self,
        processes: int,
        queue_per_client: int,
        cache: RenderCache | None = None,
        make_executor: Callable[[int], Executor] | None = None,
    ) -> None:
        """``make_executor`` (given the process count) exists for tests of the scheduling."""
        self.processes = processes
        self.queue_per_client = queue_per_client
        self.cache = cache or RenderCache()
        self._make_executor = make_executor or _process_pool
        self._executor: Executor | None = None
        self._lanes = _Lanes()
        self._free = processes
        self._rendering: dict[Hashable, asyncio.Future[bytes]] = {}
        self._closed = False
        self.rendered = 0
        """Renders finished (successfully) since start."""
        self.refused = 0
        """Requests refused with ``too_many_renders`` since start."""

    def waiting(self) -> int:
        """Renders waiting for a process now."""
        return sum(len(queue) for queue in self._lanes.waiting.values())

    def cached(self, key: Hashable) -> bytes | None:
        """The bytes rendered for ``key`` before, if kept."""
        return self.cache.find(key)

    async def render(
        self,
        client: str,
        key: Hashable,
        function: Callable[..., bytes],
        *args: Any,
        prepare: Callable[[], Awaitable[tuple[Any, ...]]] | None = None,
    ) -> bytes:
        """``function(*prepared, *args)`` run in a render process in ``client``'s lane, kept
        under ``key``; ``prepare`` (awaited only when ``key`` is neither kept nor being
        rendered) gives the leading arguments. A request of a key kept or being rendered gets
        those bytes. Exceptions of ``prepare`` and ``function`` are raised here; 429
        ``too_many_renders`` when the client's queue is full."""
        found = self.cache.find(key)
        if found is not None:
            return found
        twin = self._rendering.get(key)
        if twin is None:
            if self._closed:
                raise RuntimeError("the render pool is shut down")
            self._admit(client)
            twin = asyncio.get_running_loop().create_future()
            self._rendering[key] = twin
            self._lanes.preparing[client] = self._lanes.preparing.get(client, 0) + 1
            try:
                prepared = await prepare() if prepare is not None else ()
            except BaseException as exc:
                self._rendering.pop(key, None)
                twin.set_exception(exc)
                twin.exception()  # retrieved: raised here (and to any twin)
                raise
            finally:
                self._lanes.done_preparing(client)
            self._enqueue(_Render(client, key, function, (*prepared, *args), twin))
        # shielded: a request that goes away does not cancel a render others may wait for
        return await asyncio.shield(twin)

    def _admit(self, client: str) -> None:
        """429 ``too_many_renders`` when ``client`` has its whole queue waiting or rendering."""
        queued = self._lanes.queued(client)
        if queued >= self.queue_per_client:
            self.refused += 1
            raise ApiError(
                429,
                "too_many_renders",
                f"this client has {queued} plots waiting or rendering, at most "
                f"{self.queue_per_client} (TRAJOPT_RENDER_QUEUE_PER_CLIENT); retry after "
                f"{RENDER_RETRY_AFTER_S} s",
                headers={"Retry-After": str(RENDER_RETRY_AFTER_S)},
            )

    def _enqueue(self, render: _Render) -> None:
        lanes = self._lanes
        mine = lanes.waiting.setdefault(render.client, deque())
        mine.append(render)
        if len(mine) == 1 and render.client not in lanes.busy:
            lanes.turns.append(render.client)
        self._feed()

    def _feed(self) -> None:
        """Start the next client's next render while a process is free."""
        lanes = self._lanes
        while self._free > 0 and lanes.turns:
            client = lanes.turns.popleft()
            render = lanes.waiting[client].popleft()
            if not lanes.waiting[client]:
                del lanes.waiting[client]
            lanes.busy.add(client)
            self._free -= 1
            self._start(render)

    def _start(self, render: _Render) -> None:
        loop = asyncio.get_running_loop()
        try:
            future = self._pool().submit(render.function, *render.args)
        except BrokenProcessPool as exc:
            self._finished(render, None, exc)
            return

        def settled(done: Future[bytes]) -> None:
            if done.cancelled():  # shut down
                return
            error = done.exception()
            made = None if error is not None else done.result()
            with contextlib.suppress(RuntimeError):  # the loop closed meanwhile
                loop.call_soon_threadsafe(self._finished, render, made, error)

        future.add_done_callback(settled)

    def _finished(self, render: _Render, made: bytes | None, error: BaseException | None) -> None:
        lanes = self._lanes
        self._free += 1
        lanes.busy.discard(render.client)
        if render.client in lanes.waiting:
            lanes.turns.append(render.client)
        self._rendering.pop(render.key, None)
        if isinstance(error, BrokenProcessPool):
            self._replace_broken()
            error = ApiError(
                503,
                "render_unavailable",
                "a plot-rendering process stopped; it is being restarted, retry after "
                f"{RENDER_RETRY_AFTER_S} s",
                headers={"Retry-After": str(RENDER_RETRY_AFTER_S)},
            )
        if not render.done.done():
            if error is not None:
                render.done.set_exception(error)
            elif made is not None:
                self.rendered += 1
                self.cache.keep(render.key, made)
                render.done.set_result(made)
        if not self._closed:
            self._feed()

    def _pool(self) -> Executor:
        """The executor, started on first use."""
        if self._executor is None:
            self._executor = self._make_executor(self.processes)
        return self._executor

    def _replace_broken(self) -> None:
        broken, self._executor = self._executor, None
        if broken is not None and getattr(broken, "_broken", False):
            log.warning("a plot-rendering process died; starting new ones")
            broken.shutdown(wait=False, cancel_futures=True)
        elif broken is not None:
            self._executor = broken

    def shutdown(self) -> None:
        """Kill the render processes (a render has nothing worth a graceful stop)."""
        self._closed = True
        executor, self._executor = self._executor, None
        if executor is None:
            return
        processes = list((getattr(executor, "_processes", None) or {}).values())
        for process in processes:
            if process.is_alive():
                process.kill()
        for process in processes:
            process.join(STOP_JOIN_TIMEOUT_S)
        with contextlib.suppress(Exception):
            executor.shutdown(wait=True, cancel_futures=True)
