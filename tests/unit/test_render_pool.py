"""The scheduling of plot renders (app.render_pool), pure logic on one thread standing for the
render processes: one render of a client at a time, clients in turn, a bounded queue per client,
one render for concurrent requests of one plot, and kept plots served without a render."""

from __future__ import annotations

import asyncio
import threading
from concurrent.futures import Executor, ThreadPoolExecutor

import pytest

from app.errors import ApiError
from app.render_pool import RenderPool


def _pool(queue_per_client: int = 8) -> RenderPool:
    def threads(processes: int) -> Executor:
        return ThreadPoolExecutor(processes)

    return RenderPool(1, queue_per_client, make_executor=threads)


class Renders:
    """Render functions that log their start and wait until released (one gate for all)."""

    def __init__(self) -> None:
        self.started: list[str] = []
        self.gate = threading.Event()

    def render(self, label: str) -> bytes:
        self.started.append(label)
        self.gate.wait(5)
        return label.encode()


def test_clients_take_turns_and_another_client_waits_for_one_render_only() -> None:
    pool, renders = _pool(), Renders()

    async def run() -> list[bytes]:
        first = [
            asyncio.create_task(pool.render("a", f"a{i}", renders.render, f"a{i}"))
            for i in range(4)
        ]
        await asyncio.sleep(0.05)  # a0 is rendering, a1..a3 wait in a's queue
        late = [
            asyncio.create_task(pool.render("b", "b0", renders.render, "b0")),
            asyncio.create_task(pool.render("c", "c0", renders.render, "c0")),
        ]
        await asyncio.sleep(0.05)
        renders.gate.set()
        return list(await asyncio.gather(*first, *late))

    made = asyncio.run(run())
    assert made == [b"a0", b"a1", b"a2", b"a3", b"b0", b"c0"]
    # b and c each waited for a0 only (then for each other's turn), not for a's whole queue
    assert renders.started == ["a0", "b0", "c0", "a1", "a2", "a3"]
    pool.shutdown()


def test_a_full_queue_is_refused_with_retry_after_and_other_clients_are_not() -> None:
    pool, renders = _pool(queue_per_client=2), Renders()

    async def run() -> None:
        held = [
            asyncio.create_task(pool.render("a", f"a{i}", renders.render, f"a{i}"))
            for i in range(2)
        ]
        await asyncio.sleep(0.05)
        with pytest.raises(ApiError) as refused:
            await pool.render("a", "a2", renders.render, "a2")
        assert (refused.value.status, refused.value.code) == (429, "too_many_renders")
        assert refused.value.headers == {"Retry-After": "2"}
        other = asyncio.create_task(pool.render("b", "b0", renders.render, "b0"))
        await asyncio.sleep(0.05)
        renders.gate.set()
        assert await other == b"b0"
        await asyncio.gather(*held)

    asyncio.run(run())
    pool.shutdown()


def test_one_render_per_key_and_kept_plots_are_not_rendered_again() -> None:
    pool, renders = _pool(queue_per_client=1), Renders()

    async def run() -> list[bytes]:
        twins = [
            asyncio.create_task(pool.render(client, "k", renders.render, "k"))
            for client in ("a", "a", "b")
        ]
        await asyncio.sleep(0.05)
        renders.gate.set()
        made = await asyncio.gather(*twins)
        return [*made, await pool.render("c", "k", renders.render, "k")]

    assert asyncio.run(run()) == [b"k"] * 4
    assert renders.started == ["k"]  # a's second request did not count against its queue
    pool.shutdown()


def test_arguments_are_prepared_once_and_errors_reach_the_request() -> None:
    pool, prepared = _pool(), []

    def fail(_: str) -> bytes:
        raise KeyError("no such plot")

    async def prepare() -> tuple[str]:
        prepared.append(1)
        await asyncio.sleep(0.02)
        return ("x",)

    async def run() -> None:
        twins = [
            asyncio.create_task(pool.render("a", "k", bytes.upper, prepare=prepare)),
            asyncio.create_task(pool.render("a", "k", bytes.upper, prepare=prepare)),
        ]
        errors = await asyncio.gather(*twins, return_exceptions=True)
        # bytes.upper("x"): the prepared argument was passed, and both requests got the error
        assert [type(e) for e in errors] == [TypeError, TypeError]
        with pytest.raises(KeyError):
            await pool.render("a", "f", fail, "x")

    asyncio.run(run())
    assert prepared == [1]
    pool.shutdown()
