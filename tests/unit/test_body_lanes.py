"""Per-client lanes of large request bodies (app.body_lanes): one body of a client at a time,
a bounded share of the time for that client, and no wait for any other client."""

from __future__ import annotations

import asyncio
import time

import pytest

from app.body_lanes import LARGE_BODY_BYTES, BodyLanes, is_large


async def _hold(
    lanes: BodyLanes, client: str, seconds: float, log: list[tuple[str, float]]
) -> None:
    async with lanes.lane(client):
        log.append((client, time.monotonic()))
        await asyncio.sleep(seconds)


def test_one_body_of_a_client_at_a_time_then_its_cool_down() -> None:
    """Two bodies of one client: the second starts after the first ends plus the cool-down
    (work × (1/share − 1) = 20 ms × 1 at share 0.5). Sleeps of 20 ms on an event loop are
    accurate to a few ms; 5 ms of slack absorbs the scheduler."""
    lanes = BodyLanes(share=0.5)
    log: list[tuple[str, float]] = []

    async def run() -> None:
        await asyncio.gather(_hold(lanes, "a", 0.02, log), _hold(lanes, "a", 0.02, log))

    asyncio.run(run())
    gap = log[1][1] - log[0][1]
    assert gap >= 0.04 - 0.005, gap
    assert lanes.clients() == 0


def test_another_client_does_not_wait() -> None:
    """Client b enters while a holds its lane: b starts within a few ms, not after a."""
    lanes = BodyLanes(share=0.25)
    log: list[tuple[str, float]] = []

    async def run() -> None:
        await asyncio.gather(_hold(lanes, "a", 0.05, log), _hold(lanes, "b", 0.0, log))

    asyncio.run(run())
    started = dict(log)
    assert started["b"] - started["a"] < 0.02


def test_the_cool_down_is_forgotten_once_past() -> None:
    """Idle clients whose cool-down has passed are pruned once many are remembered."""
    lanes = BodyLanes(share=1.0)

    async def run() -> None:
        for number in range(200):
            async with lanes.lane(f"client-{number}"):
                pass

    asyncio.run(run())
    assert len(lanes._ready_at) <= 65


def test_share_must_be_a_fraction() -> None:
    with pytest.raises(ValueError, match="share"):
        BodyLanes(share=0.0)


@pytest.mark.parametrize(
    ("header", "large"),
    [(None, True), ("12", False), (str(LARGE_BODY_BYTES), False), ("65537", True), ("x", True)],
)
def test_large_is_by_declared_length(header: str | None, large: bool) -> None:
    assert is_large(header) is large
