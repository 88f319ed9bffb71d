"""Plot isolation between clients: another client's first plot and its reads, alone and while one
client asks for many plots at once on several connections.

Starts an embedded ``trajopt serve`` (api-keys mode, one key per client, one job process, read
rate limits off) in a temporary folder. Client A and client B get finished jobs of the same
problem. Then B, in three windows of ``--window-s``:

- reads alone: B reads its job's status every 0.05 s;
- first plot alone: B asks for a plot of one of its jobs (never rendered before: its first
  plot) while reading as before;
- under load: A keeps ``--connections`` connections busy with plots of its own jobs never
  rendered before (every plot of every job, PNG and SVG, the convergence plots, the longest to
  render, first), and B does as in the second window with its other job (the same plot of the
  same problem: the same work).

Printed: B's first-plot time and its reads' p50 / p95, how many of A's plots arrived while B
waited for its first, and the CPU the API process itself used (Linux). With ``--batch`` also
B's reads while A asks on ``--batch-connections`` connections for one batch's plot, and for
that batch's status (a read of about the same cost, for reference).

    python -m bench.plot_isolation
    python -m bench.plot_isolation --connections 8 --batch --output plots.json
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from itertools import cycle
from pathlib import Path
from typing import Any

import httpx

from bench.service_overhead import ROOT, TERMINAL, _free_port, _Process

SECRET = "bench-only-0d7e3b9a5c1f4e8d2a6b0c9e7f5a3d1b"
SCENARIO = "rlv-min-heat-load"
"""The problem both clients solve (its default options: about 120 nodes, under a second)."""
PLOT = "convergence"
"""The plot B asks for first, and the first ones A asks for: the longest to render (1-1.5 s,
several times any other plot), so A's render in progress is never longer than B's own."""
READ_GAP_S = 0.05
"""B's pace of status reads (20 a second: within the default read rate limit for a minute)."""
FORMATS = ("png", "svg")


@dataclass
class ClientFigures:
    """What the other client saw during one window."""

    first_plot_s: float | None
    plot_span: tuple[float, float] | None
    """When the first plot was asked for and when it arrived (``time.perf_counter``)."""
    read_p50_ms: float
    read_p95_ms: float
    read_max_ms: float
    reads: int
    read_ms: list[float]
    """Every read's time, in order."""
    server_cpu: float = 0.0
    """CPU seconds the API process used per second of the window (its children apart)."""
    window: tuple[float, float] = (0.0, 0.0)
    """When the window began and ended (``time.perf_counter``)."""


@dataclass
class LoadCount:
    """The answers the loading client got, by status code."""

    answers: dict[int, int] = field(default_factory=dict)
    rendered_at: list[float] = field(default_factory=list)
    """When each 200 arrived (``time.perf_counter``)."""

    def add(self, status: int) -> None:
        self.answers[status] = self.answers.get(status, 0) + 1
        if status == 200:
            self.rendered_at.append(time.perf_counter())

    def between(self, start: float, end: float) -> int:
        """Plots received between ``start`` and ``end``."""
        return sum(1 for t in self.rendered_at if start <= t <= end)


def cpu_seconds(pid: int | None) -> float:
    """CPU time (user + system, seconds) process ``pid`` used so far, its children apart (0 when
    unknown: not Linux, or no pid)."""
    if pid is None:
        return 0.0
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _p95(values: Sequence[float]) -> float:
    return statistics.quantiles(values, n=20, method="inclusive")[18]


def create_key(env: dict[str, str], client: str) -> str:
    """A new API key of ``client`` (``trajopt keys create``)."""
    out = subprocess.run(
        [sys.executable, "-m", "app.cli", "keys", "create", "--client", client],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    )
    return out.stdout.strip()


def finished_jobs(http: httpx.Client, body: dict[str, Any], count: int) -> list[str]:
    """Submit ``count`` jobs of ``body`` and wait until each succeeded; their ids."""
    ids = []
    for _ in range(count):
        answer = http.post("/v1/jobs", json=body)
        answer.raise_for_status()
        ids.append(answer.json()["id"])
    for job_id in ids:
        deadline = time.monotonic() + 300
        while (job := http.get(f"/v1/jobs/{job_id}").json())["status"] not in TERMINAL:
            if time.monotonic() > deadline:
                raise RuntimeError(f"job {job_id} not finished in 300 s: {job}")
            time.sleep(0.1)
        if job["status"] != "succeeded":
            raise RuntimeError(f"job {job_id} did not succeed: {job}")
    return ids


def plot_paths(http: httpx.Client, job_ids: Sequence[str]) -> list[str]:
    """The path of every plot of every job, in every format; :data:`PLOT` first."""
    paths = []
    for job_id in job_ids:
        names = http.get(f"/v1/jobs/{job_id}/plots").json()
        paths += [f"/v1/jobs/{job_id}/plots/{n}.{f}" for n in names for f in FORMATS]
    return sorted(paths, key=lambda path: f"/{PLOT}." not in path)


@contextmanager
def render_load(
    base_url: str, api_key: str, paths: Sequence[str], connections: int
) -> Iterator[LoadCount]:
    """``connections`` threads asking for ``paths`` in turn (each path once, then round again)
    until the block ends; a 429 is waited out for its Retry-After as a client would."""
    stop = threading.Event()
    count = LoadCount()
    lock = threading.Lock()
    order = cycle(paths)

    def run() -> None:
        with httpx.Client(base_url=base_url, headers={"X-API-Key": api_key}, timeout=120) as http:
            while not stop.is_set():
                with lock:
                    path = next(order)
                try:
                    answer = http.get(path)
                except httpx.HTTPError:
                    continue
                with lock:
                    count.add(answer.status_code)
                if answer.status_code == 429:
                    stop.wait(float(answer.headers.get("retry-after", "1")))

    threads = [threading.Thread(target=run, daemon=True) for _ in range(connections)]
    for thread in threads:
        thread.start()
    try:
        yield count
    finally:
        stop.set()
        for thread in threads:
            thread.join(timeout=150)


def other_client(
    base_url: str,
    api_key: str,
    job_id: str,
    plot: str | None,
    window_s: float,
    server_pid: int | None = None,
) -> ClientFigures:
    """Client B over ``window_s``: its status reads every :data:`READ_GAP_S` on one connection
    and, on another, its first plot ``plot`` of ``job_id`` (None: reads only); the CPU of the
    API process ``server_pid`` meanwhile."""
    cpu_start, wall_start = cpu_seconds(server_pid), time.perf_counter()
    headers = {"X-API-Key": api_key}
    times: list[float] = []

    def read() -> None:
        with httpx.Client(base_url=base_url, headers=headers, timeout=60) as http:
            end = time.monotonic() + window_s
            while time.monotonic() < end:
                started = time.perf_counter()
                http.get(f"/v1/jobs/{job_id}").raise_for_status()
                times.append(time.perf_counter() - started)
                time.sleep(READ_GAP_S)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    span: tuple[float, float] | None = None
    if plot is not None:
        with httpx.Client(base_url=base_url, headers=headers, timeout=120) as http:
            started = time.perf_counter()
            answer = http.get(f"/v1/jobs/{job_id}/plots/{plot}.png")
            span = (started, time.perf_counter())
            if answer.status_code != 200:
                raise RuntimeError(f"B's plot: {answer.status_code} {answer.text[:200]}")
    reader.join()
    wall_end = time.perf_counter()
    cpu = (cpu_seconds(server_pid) - cpu_start) / (wall_end - wall_start)
    first = None if span is None else span[1] - span[0]
    return ClientFigures(
        first,
        span,
        1e3 * statistics.median(times),
        1e3 * _p95(times),
        1e3 * max(times),
        len(times),
        [round(1e3 * t, 2) for t in times],
        cpu,
        (wall_start, wall_end),
    )


def isolation(
    base_url: str,
    keys: tuple[str, str],
    a_jobs: Sequence[str],
    b_jobs: tuple[str, str],
    connections: int,
    window_s: float,
    server_pid: int | None = None,
    lead_s: float = 0.5,
) -> dict[str, Any]:
    """B's reads alone ("reads"), B's first plot alone (of ``b_jobs[0]``, with its reads:
    "alone"), then both under A's render load on ``connections`` connections (first plot of
    ``b_jobs[1]``, ``lead_s`` after A started: "loaded"); with the CPU the API process
    ``server_pid`` used in each window."""
    key_a, key_b = keys
    with httpx.Client(base_url=base_url, headers={"X-API-Key": key_a}, timeout=120) as http:
        paths = plot_paths(http, a_jobs)
        http.get(paths.pop()).raise_for_status()  # the server's first plot ever: start-up costs
    reads = other_client(base_url, key_b, b_jobs[0], None, window_s, server_pid)
    alone = other_client(base_url, key_b, b_jobs[0], PLOT, window_s, server_pid)
    with render_load(base_url, key_a, paths, connections) as count:
        time.sleep(lead_s)
        loaded = other_client(base_url, key_b, b_jobs[1], PLOT, window_s, server_pid)
    assert loaded.plot_span is not None
    return {
        "reads": asdict(reads),
        "alone": asdict(alone),
        "loaded": asdict(loaded),
        "a_answers": count.answers,
        "a_plots_while_b_waited": count.between(*loaded.plot_span),
        "a_plots_in_loaded_window": count.between(*loaded.window),
    }


def batch_isolation(
    base_url: str,
    keys: tuple[str, str],
    b_job: str,
    connections: int,
    window_s: float,
    server_pid: int | None = None,
) -> dict[str, Any]:
    """B's reads alone, while A asks for one finished batch's plot on ``connections``
    connections, and (for reference) while A asks for the same batch's status as often."""
    key_a, key_b = keys
    with httpx.Client(base_url=base_url, headers={"X-API-Key": key_a}, timeout=300) as http:
        grid = {"parameters": [{"path": "/method/nodes", "values": [30, 40, 50]}]}
        answer = http.post("/v1/batches", json={"base": {"scenario": SCENARIO}, "grid": grid})
        answer.raise_for_status()
        batch_id = answer.json()["id"]
        deadline = time.monotonic() + 300
        while http.get(f"/v1/batches/{batch_id}").json()["status"] == "running":
            if time.monotonic() > deadline:
                raise RuntimeError(f"batch {batch_id} not finished in 300 s")
            time.sleep(0.2)
    report: dict[str, Any] = {
        "alone": asdict(other_client(base_url, key_b, b_job, None, window_s, server_pid))
    }
    for label, path in (
        ("plot", f"/v1/batches/{batch_id}/plot.png"),
        ("status", f"/v1/batches/{batch_id}"),
    ):
        with render_load(base_url, key_a, [path], connections) as count:
            time.sleep(0.5)
            loaded = other_client(base_url, key_b, b_job, None, window_s, server_pid)
        report[label] = {**asdict(loaded), "a_answers": count.answers}
    return report


@contextmanager
def embedded_server(folder: Path, **settings: str) -> Iterator[tuple[str, tuple[str, str], int]]:
    """An embedded server in api-keys mode with one job process, read rate limits off (client
    A's load would otherwise be cut short) and ``settings`` (environment variables); its URL,
    two clients' keys and its process id."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("TRAJOPT_")}
    for name in ("DATABASE_URL", "REDIS_URL", "CELERY_BROKER_URL"):
        env.pop(name, None)
    env.update(
        TRAJOPT_DATA_DIR=str(folder),
        TRAJOPT_LOCAL_WORKERS="1",
        TRAJOPT_AUTH_MODE="api-keys",
        TRAJOPT_API_KEY_SECRET=SECRET,
        TRAJOPT_RATE_READ_PER_WINDOW="0",
        **settings,
    )
    keys = (create_key(env, "render-load"), create_key(env, "other"))
    port = _free_port()
    api = _Process(["serve", "--host", "127.0.0.1", "--port", str(port)], env, folder / "api.log")
    try:
        api.wait_for("Application startup complete", 90)
        yield f"http://127.0.0.1:{port}", keys, api.proc.pid
    finally:
        api.stop()


def _line(label: str, figures: dict[str, Any]) -> str:
    first = figures["first_plot_s"]
    shown = f"first plot {first:.2f} s, " if first is not None else ""
    return (
        f"  {label}: {shown}reads p50 {figures['read_p50_ms']:.0f} ms, "
        f"p95 {figures['read_p95_ms']:.0f} ms "
        f"(max {figures['read_max_ms']:.0f} ms, {figures['reads']} reads); the API process "
        f"used {figures['server_cpu']:.2f} CPU s/s"
    )


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print (and optionally write) the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--connections", type=int, default=6, help="A's rendering connections")
    parser.add_argument("--a-jobs", type=int, default=2, help="A's jobs (each ~16 plots)")
    parser.add_argument("--window-s", type=float, default=4.0, help="B's measuring window")
    parser.add_argument("--batch", action="store_true", help="also A on one batch's plot")
    parser.add_argument("--batch-connections", type=int, default=16)
    parser.add_argument(
        "--render-processes", type=int, help="TRAJOPT_RENDER_PROCESSES (default: the server's)"
    )
    parser.add_argument("--output", type=Path, help="also write the figures as JSON")
    args = parser.parse_args(argv)
    settings = {}
    if args.render_processes is not None:
        settings["TRAJOPT_RENDER_PROCESSES"] = str(args.render_processes)

    body = {"scenario": SCENARIO}
    with (
        tempfile.TemporaryDirectory(prefix="trajopt-bench-") as tmp,
        embedded_server(Path(tmp), **settings) as (base_url, keys, pid),
    ):
        with httpx.Client(base_url=base_url, headers={"X-API-Key": keys[0]}, timeout=60) as a:
            a_jobs = finished_jobs(a, body, args.a_jobs)
        with httpx.Client(base_url=base_url, headers={"X-API-Key": keys[1]}, timeout=60) as b:
            b_jobs = finished_jobs(b, body, 2)
        report: dict[str, Any] = {
            "plots": isolation(
                base_url,
                keys,
                a_jobs,
                (b_jobs[0], b_jobs[1]),
                args.connections,
                args.window_s,
                pid,
            )
        }
        if args.batch:
            report["batch"] = batch_isolation(
                base_url, keys, b_jobs[0], args.batch_connections, args.window_s, pid
            )

    plots = report["plots"]
    print(f"client B's first plot ({PLOT}.png) and its status reads every {READ_GAP_S} s:")
    print(_line("reads alone", plots["reads"]))
    print(_line("first plot alone", plots["alone"]))
    print(_line(f"under A's renders on {args.connections} connections", plots["loaded"]))
    print(
        f"  under load / alone: first plot "
        f"{plots['loaded']['first_plot_s'] / plots['alone']['first_plot_s']:.2f}, reads p95 "
        f"{plots['loaded']['read_p95_ms'] / plots['reads']['read_p95_ms']:.2f}; "
        f"A's answers {plots['a_answers']}, {plots['a_plots_while_b_waited']} of its plots "
        "arrived while B waited for its first"
    )
    if args.batch:
        batch = report["batch"]
        print(f"client B's status reads while A asks on {args.batch_connections} connections for:")
        print(_line("nothing (alone)", batch["alone"]))
        print(_line(f"one batch's plot (A's answers {batch['plot']['a_answers']})", batch["plot"]))
        print(
            _line(
                f"that batch's status (A's answers {batch['status']['a_answers']})", batch["status"]
            )
        )
    if args.output:
        args.output.write_text(json.dumps(report, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
