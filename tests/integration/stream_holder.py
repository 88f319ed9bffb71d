"""A load client for the stream tests, run as its own process: open N event streams of one job
and read them until stopped.

``python -m tests.integration.stream_holder BASE_URL API_KEY JOB_ID N`` prints
``opened <ok> refused <other>`` once every stream has its response head, then every second
``bytes <total>`` (what all streams received so far), until SIGTERM.
"""

from __future__ import annotations

import asyncio
import signal
import sys

import httpx


async def hold(base_url: str, api_key: str, job_id: str, count: int) -> None:
    """Open ``count`` streams at once and drain them until the process is told to stop."""
    received = 0
    answered = asyncio.Event()
    statuses: list[int] = []
    stop = asyncio.Event()
    asyncio.get_running_loop().add_signal_handler(signal.SIGTERM, stop.set)
    limits = httpx.Limits(max_connections=count + 10, max_keepalive_connections=0)
    timeout = httpx.Timeout(30.0, read=None)
    headers = {"X-API-Key": api_key}
    async with httpx.AsyncClient(
        base_url=base_url, limits=limits, timeout=timeout, headers=headers
    ) as client:

        async def one() -> None:
            nonlocal received
            async with client.stream("GET", f"/v1/jobs/{job_id}/events") as response:
                statuses.append(response.status_code)
                if len(statuses) == count:
                    answered.set()
                async for chunk in response.aiter_raw():
                    received += len(chunk)

        tasks = [asyncio.create_task(one()) for _ in range(count)]
        await answered.wait()
        ok = sum(1 for status in statuses if status == 200)
        print(f"opened {ok} refused {len(statuses) - ok}", flush=True)
        while not stop.is_set():
            try:
                await asyncio.wait_for(stop.wait(), 1.0)
            except TimeoutError:
                print(f"bytes {received}", flush=True)
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)


if __name__ == "__main__":
    url, key, job, n = sys.argv[1:5]
    asyncio.run(hold(url, key, job, int(n)))
