"""One client's plots do not slow another's: two clients (api-keys mode) of one embedded server,
client A asking for many plots at once on six connections, client B for its first plot and its
job's status meanwhile (the measurement of ``python -m bench.plot_isolation``).

What it checks is the scheduling, not the machine's speed: how many of A's plots arrive while B
waits for its first (an order of events), and the API process's own CPU time per answer under
A's load against B's reads alone (CPU seconds, which other processes' load does not inflate).
The wall times (B's first plot, its reads' p95) are printed by ``python -m bench.plot_isolation``.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from bench.plot_isolation import SCENARIO, finished_jobs, isolation
from tests.integration.harness import ApiServer, create_api_key, embedded_env

pytestmark = pytest.mark.slow

SECRET = "e2e-only-7a2c9e4f1b3d5a6c8e0f2b4d6a8c0e1f"


@pytest.fixture
def server(tmp_path: Path) -> Iterator[tuple[ApiServer, tuple[str, str]]]:
    env = embedded_env(
        tmp_path,
        TRAJOPT_AUTH_MODE="api-keys",
        TRAJOPT_API_KEY_SECRET=SECRET,
        TRAJOPT_RENDER_PROCESSES="1",
    )
    keys = (create_api_key(env, "renders-a-lot"), create_api_key(env, "other"))
    api = ApiServer(env, tmp_path / "serve.log")
    api.start_and_wait()
    try:
        yield api, keys
    finally:
        api.stop()


@pytest.mark.exclusive
def test_another_clients_first_plot_and_reads_do_not_wait_for_one_clients_renders(
    server: tuple[ApiServer, tuple[str, str]],
) -> None:
    api, keys = server
    jobs = []
    for key, count in zip(keys, (1, 2), strict=True):
        with httpx.Client(base_url=api.base_url, headers={"X-API-Key": key}, timeout=60) as http:
            jobs.append(finished_jobs(http, {"scenario": SCENARIO}, count))
    assert api.process is not None
    figures = isolation(
        api.base_url,
        keys,
        jobs[0],
        (jobs[1][0], jobs[1][1]),
        connections=6,
        window_s=3.0,
        server_pid=api.process.pid,
    )
    reads, loaded = figures["reads"], figures["loaded"]
    assert figures["a_answers"].get(200, 0) >= 2, figures  # A did render meanwhile
    # B's first plot waits for A's render in progress at most (one plot, plus one whose answer
    # may still be on its way), never for A's queue: six of A's plots arrived before it when
    # every plot of the process took its turn on one lock
    assert figures["a_plots_while_b_waited"] <= 2, figures
    # B's reads: renders in the server's own threads held its interpreter lock (p95 5-9 times
    # that of B's reads alone, the API process at 0.56-0.92 CPU s/s against 0.09-0.10); in
    # their own processes they leave the server's CPU to requests. The CPU time is the
    # measure, not the reads' wall time: another process's load moves wall times between the
    # two windows (B's first plot measured 3.5 x alone once with other work on the machine,
    # its ordering above still exact); the wall figures are the bench's to report. The API's
    # CPU is taken per answer it gave in the window: once A's plots are rendered A gets them
    # from the store, up to ~150 answers a second of ~2 ms each, as B's reads cost (the CPU
    # per second then reached 0.30-0.45 with no render in the process), where a render in the
    # process costs tens of milliseconds an answer (measured: 1.8-1.9 ms an answer under A's
    # 680-800 answers against 3.8 ms a read alone, at 0.47-0.50 CPU s/s against 0.07).
    if reads["server_cpu"] > 0:  # Linux: the API process itself does not render
        alone_s = reads["server_cpu"] * _span(reads) / reads["reads"]
        answers = loaded["reads"] + 1 + figures["a_plots_in_loaded_window"]
        loaded_s = loaded["server_cpu"] * _span(loaded) / answers
        assert loaded_s <= 2 * alone_s, (loaded_s, alone_s, figures)


def _span(window: dict[str, Any]) -> float:
    """The length of a client's window, s."""
    start, end = window["window"]
    return float(end - start)
