"""Service overhead and throughput on loopback: API + worker(s) + database, real solves.

Overhead of one job = (submit -> result fetched) minus the solver's own time (the result's
``timing.total_s``): HTTP, database writes, queueing, worker pick-up, the end notice and the
result fetch. Measured one job at a time with idle workers, then p50/p95 over ``--jobs`` jobs.
Throughput = small jobs finished per second with a full queue, for each worker count.

    python -m bench.service_overhead                        # Redis + PostgreSQL on localhost
    python -m bench.service_overhead --embedded             # SQLite + local process pool
    python -m bench.service_overhead --jobs 100 --workers 1 2 --output overhead.json

Needs no running service: it starts the API and the workers itself on free loopback ports, in a
throwaway PostgreSQL schema / Redis queue (or a temporary SQLite folder) removed afterwards.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any
from urllib.parse import quote

import httpx

from bench.stack_args import add_stack_arguments
from worker.celery_app import priority_lists

ROOT = Path(__file__).resolve().parents[1]
TERMINAL = {"succeeded", "failed", "cancelled", "timed_out"}


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


class _Process:
    """A service subprocess in its own session, stopped with its children."""

    def __init__(self, args: list[str], env: dict[str, str], log: Path) -> None:
        self.log = log
        handle = log.open("w")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "app.cli", *args],
            cwd=ROOT,
            env=env,
            stdout=handle,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        handle.close()

    def wait_for(self, text: str, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if text in self.log.read_text(errors="replace"):
                return
            if self.proc.poll() is not None:
                break
            time.sleep(0.1)
        raise RuntimeError(f"{self.log.name}: {text!r} not seen:\n{self.log.read_text()[-3000:]}")

    def stop(self) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGTERM)
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()


@contextmanager
def _stack(args: argparse.Namespace, workers: int, logs: Path) -> Iterator[str]:
    """Start the API (and ``workers`` Celery workers, or a local pool); yield its base URL."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("TRAJOPT_")}
    for name in ("DATABASE_URL", "REDIS_URL", "CELERY_BROKER_URL"):
        env.pop(name, None)
    # one client submits every job: the per-client rate limits would cut the run short (429)
    env.update(TRAJOPT_RATE_SUBMIT_PER_WINDOW="0", TRAJOPT_RATE_READ_PER_WINDOW="0")
    processes: list[_Process] = []
    schema = None
    if args.embedded:
        env.update(
            TRAJOPT_DATA_DIR=str(logs / f"data-{workers}"), TRAJOPT_LOCAL_WORKERS=str(workers)
        )
    else:
        import psycopg

        schema = f"trajopt_bench_{uuid.uuid4().hex[:10]}"
        with psycopg.connect(args.postgres_url, autocommit=True) as conn:
            conn.execute(f'CREATE SCHEMA "{schema}"')
        sep = "&" if "?" in args.postgres_url else "?"
        env.update(
            DATABASE_URL=f"{args.postgres_url}{sep}options={quote(f'-csearch_path={schema}')}",
            REDIS_URL=args.redis_url,
            TRAJOPT_QUEUE_NAME=f"trajopt-bench-{uuid.uuid4().hex[:10]}",
        )
    port = _free_port()
    try:
        api = _Process(
            ["serve", "--host", "127.0.0.1", "--port", str(port)], env, logs / f"api-{workers}.log"
        )
        processes.append(api)
        api.wait_for("Application startup complete", 90)
        if not args.embedded:
            for index in range(workers):
                worker = _Process(
                    ["worker", "--concurrency", "1"], env, logs / f"worker-{workers}-{index}.log"
                )
                processes.append(worker)
                worker.wait_for(" ready.", 90)
        yield f"http://127.0.0.1:{port}"
    finally:
        for process in reversed(processes):
            process.stop()
        if schema is not None:
            import psycopg
            import redis

            with psycopg.connect(args.postgres_url, autocommit=True) as conn:
                conn.execute(f'DROP SCHEMA IF EXISTS "{schema}" CASCADE')
            queue = env["TRAJOPT_QUEUE_NAME"]
            client = redis.Redis.from_url(args.redis_url)
            bindings = (f"_kombu.binding.{queue}", f"_kombu.binding_permanent.{queue}")
            client.delete(*priority_lists(queue), *bindings)
            if client.keys("*") == [b"_kombu.binding_deadlines"]:
                client.delete("_kombu.binding_deadlines")
            client.close()


def _body(args: argparse.Namespace) -> dict[str, Any]:
    method = {"nodes": args.nodes, "max_iterations": args.max_iterations}
    return {"scenario": args.scenario, "method": method}


def _wait_end(client: httpx.Client, job_id: str) -> None:
    with client.stream("GET", f"/v1/jobs/{job_id}/events", timeout=300) as response:
        for line in response.iter_lines():
            if line.startswith("event:") and line.split(":", 1)[1].strip() == "end":
                return
    raise RuntimeError(f"job {job_id}: the event stream ended without an end event")


def _solve_time(result: dict[str, Any]) -> float:
    timing = result.get("timing") or {}
    return float(timing.get("total_s", timing.get("wall_s", 0.0)))


def measure_overhead(base_url: str, args: argparse.Namespace) -> dict[str, Any]:
    """Sequential jobs, each submitted once the previous result was fetched."""
    overheads, solves, waits = [], [], []
    phases: dict[str, list[float]] = {name: [] for name in PHASES}
    with httpx.Client(base_url=base_url, timeout=60) as client:
        for index in range(args.warmup + args.jobs):
            start = time.perf_counter()
            wall_start = time.time()
            job = client.post("/v1/jobs", json=_body(args)).json()
            submitted = time.time()
            _wait_end(client, job["id"])
            ended = time.time()
            result = client.get(f"/v1/jobs/{job['id']}/result")
            elapsed = time.perf_counter() - start
            fetched = time.time()
            if result.status_code != 200:
                raise RuntimeError(f"job {job['id']}: no result: {result.text}")
            if index < args.warmup:
                continue
            solve = _solve_time(result.json())
            overheads.append(elapsed - solve)
            solves.append(solve)
            view = client.get(f"/v1/jobs/{job['id']}").json()
            waits.append(_seconds_between(view["created_at"], view["started_at"]))
            started, finished = _epoch(view["started_at"]), _epoch(view["finished_at"])
            phases["submit (POST answered)"].append(submitted - wall_start)
            phases["answered -> attempt started"].append(started - submitted)
            phases["attempt: started -> finished, less the solve"].append(
                finished - started - solve
            )
            phases["finished -> end event received"].append(ended - finished)
            phases["end event -> result fetched"].append(fetched - ended)
    quantiles = statistics.quantiles(overheads, n=20, method="inclusive")
    return {
        "phases_p50_ms": {k: 1e3 * statistics.median(v) for k, v in phases.items()},
        "jobs": len(overheads),
        "overhead_p50_ms": 1e3 * statistics.median(overheads),
        "overhead_p95_ms": 1e3 * quantiles[18],
        "overhead_max_ms": 1e3 * max(overheads),
        "queue_wait_p50_ms": 1e3 * statistics.median(waits),
        "solve_p50_s": statistics.median(solves),
    }


PHASES = (
    "submit (POST answered)",
    "answered -> attempt started",
    "attempt: started -> finished, less the solve",
    "finished -> end event received",
    "end event -> result fetched",
)
"""Where a job's overhead goes (client clock against the server's timestamps: one machine)."""


def _epoch(stamp: str) -> float:
    from datetime import datetime

    return datetime.fromisoformat(stamp).timestamp()


def _seconds_between(first: str, second: str) -> float:
    from datetime import datetime

    return (datetime.fromisoformat(second) - datetime.fromisoformat(first)).total_seconds()


def measure_throughput(base_url: str, args: argparse.Namespace, workers: int) -> dict[str, Any]:
    """Submit ``--throughput-jobs`` jobs at once; jobs finished per second until the last."""
    with httpx.Client(base_url=base_url, timeout=60) as client:
        start = time.perf_counter()
        ids = [
            client.post("/v1/jobs", json=_body(args)).json()["id"]
            for _ in range(args.throughput_jobs)
        ]
        pending = set(ids)
        while pending:
            time.sleep(0.05)
            page = client.get("/v1/jobs", params={"status": ["queued", "running"], "limit": 100})
            pending &= {job["id"] for job in page.json()["items"]}
            if page.json()["total"] == 0:
                pending.clear()
        elapsed = time.perf_counter() - start
        statuses = [client.get(f"/v1/jobs/{i}").json()["status"] for i in ids]
    return {
        "workers": workers,
        "jobs": len(ids),
        "seconds": elapsed,
        "jobs_per_s": len(ids) / elapsed,
        "statuses": {s: statuses.count(s) for s in sorted(set(statuses))},
    }


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print (and optionally write) the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--embedded", action="store_true", help="SQLite + local pool, no Redis")
    parser.add_argument("--jobs", type=int, default=50, help="jobs for the overhead percentiles")
    parser.add_argument("--warmup", type=int, default=3)
    parser.add_argument("--throughput-jobs", type=int, default=30)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--scenario", default="rlv-min-heat-load")
    parser.add_argument("--nodes", type=int, default=20)
    parser.add_argument("--max-iterations", type=int, default=5)
    add_stack_arguments(parser, redis_db=13)
    args = parser.parse_args(argv)
    if args.jobs < 20:
        parser.error("--jobs must be at least 20 for a 95th percentile")

    report: dict[str, Any] = {
        "mode": "embedded (SQLite, local pool)" if args.embedded else "Redis + PostgreSQL + Celery",
        "job": _body(args),
        "throughput": [],
    }
    with tempfile.TemporaryDirectory(prefix="trajopt-bench-") as tmp:
        for index, workers in enumerate(args.workers):
            with _stack(args, workers, Path(tmp)) as base_url:
                if index == 0:
                    report["overhead"] = {"workers": workers, **measure_overhead(base_url, args)}
                report["throughput"].append(measure_throughput(base_url, args, workers))

    overhead = report["overhead"]
    print(f"mode: {report['mode']}; job: {json.dumps(report['job'])}")
    print(
        f"overhead over {overhead['jobs']} jobs ({overhead['workers']} idle worker): "
        f"p50 {overhead['overhead_p50_ms']:.1f} ms, p95 {overhead['overhead_p95_ms']:.1f} ms, "
        f"max {overhead['overhead_max_ms']:.1f} ms; queue wait p50 "
        f"{overhead['queue_wait_p50_ms']:.1f} ms; solve p50 {overhead['solve_p50_s']:.3f} s"
    )
    for name, value in overhead["phases_p50_ms"].items():
        print(f"  {name}: p50 {value:.1f} ms")
    for row in report["throughput"]:
        print(
            f"throughput, {row['workers']} worker process(es): {row['jobs_per_s']:.2f} jobs/s "
            f"({row['jobs']} jobs in {row['seconds']:.1f} s; {row['statuses']})"
        )
    if args.output:
        args.output.write_text(json.dumps(report, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
