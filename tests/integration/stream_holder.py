"""A load client for the stream tests, run as its own process: open N event streams of one job
and read them until stopped.

``python -m tests.integration.stream_holder BASE_URL API_KEY JOB_ID N`` prints
``opened <ok> refused <other>`` once every stream has its response head, then every second
``bytes <total>`` (what all streams received so far, chunk framing included), until SIGTERM.

Each stream is a plain HTTP/1.1 request on its own asyncio connection, read in large blocks:
a load generator that spends little CPU, so on a 2-core machine the measured server, not the
client holding its streams, gets the cores. With a full HTTP client parsing every chunk of the
300 streams, the other client's read p95 in ``test_stream_limits`` was 73-152 ms in three runs
(two over its 100 ms bar); with this one 52-60 ms.
"""

from __future__ import annotations

import asyncio
import signal
import sys
from urllib.parse import urlsplit

READ_BLOCK = 65536


async def _open(
    host: str, port: int, request: bytes
) -> tuple[int, asyncio.StreamReader, asyncio.StreamWriter]:
    """Send ``request`` on a new connection; the response's status, the reader after its head
    (the body follows) and the writer, which must be kept: a collected writer closes the
    connection."""
    reader, writer = await asyncio.open_connection(host, port)
    writer.write(request)
    await writer.drain()
    head = await reader.readuntil(b"\r\n\r\n")
    status = int(head.split(b" ", 2)[1])
    return status, reader, writer


async def hold(base_url: str, api_key: str, job_id: str, count: int) -> None:
    """Open ``count`` streams at once and drain them until the process is told to stop."""
    url = urlsplit(base_url)
    host, port = url.hostname or "127.0.0.1", url.port or 80
    request = (
        f"GET /v1/jobs/{job_id}/events HTTP/1.1\r\nHost: {host}:{port}\r\n"
        f"X-API-Key: {api_key}\r\nAccept: text/event-stream\r\n\r\n"
    ).encode()
    received = 0
    answered = asyncio.Event()
    statuses: list[int] = []
    stop = asyncio.Event()
    asyncio.get_running_loop().add_signal_handler(signal.SIGTERM, stop.set)

    async def one() -> None:
        nonlocal received
        try:
            status, reader, writer = await _open(host, port, request)
        except (OSError, asyncio.IncompleteReadError, ValueError, IndexError):
            statuses.append(0)
            if len(statuses) == count:
                answered.set()
            return
        statuses.append(status)
        if len(statuses) == count:
            answered.set()
        if status != 200:
            writer.close()
            return
        while chunk := await reader.read(READ_BLOCK):
            received += len(chunk)
        writer.close()

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
