"""Load with a fault: 200 small jobs from 4 concurrent clients while a worker, the API or the
database is lost for a while.

Starts its own API (api-keys mode, one key per client), two Celery workers and a throwaway
PostgreSQL schema and Redis queue. Each client submits its share of the jobs and then polls the
status of every job it owns until all are terminal, timing each status read; a request that
fails during the fault is retried. Once a few jobs have finished, the fault strikes:

- ``--fault worker``: worker 1 is killed with SIGKILL (its whole process group) and restarted;
- ``--fault api``: the API is killed with SIGKILL in the middle of the submissions (jobs stored
  but not yet sent are left behind) and restarted;
- ``--fault database``: every database connection of the API and the workers goes through a TCP
  forwarder, which is cut for ``--outage-s`` (running and queued jobs in flight) and restored.

At the end the database must hold every accepted job (and every job stored whose answer was
lost with the API) in a terminal state, the worker logs must show exactly one stored outcome per
job finished by a worker, every job must have become terminal within ``--job-bound-s`` of its
acceptance (a client stops waiting for one that has not, and the run fails), and no queued job
may have been stranded for longer than 30 s after the recovery: due in the outbox and unsent,
or marked sent with no message carrying it (none in the queue, none delivered to a live worker;
:mod:`bench.stranded`, sampled every half second). A failing run prints why, job by job.

    python -m bench.load_faults                       # 200 jobs, 4 clients, 2 workers
    python -m bench.load_faults --fault api --jobs 100
    python -m bench.load_faults --fault database --outage-s 20 --output load.json
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from pathlib import Path
from typing import Any
from urllib.parse import quote

import httpx

from bench.service_overhead import ROOT, TERMINAL, _free_port, _Process
from bench.stack_args import add_stack_arguments
from bench.stranded import StrandMonitor, explain
from bench.tcp_proxy import TcpProxy
from worker.celery_app import priority_lists

SECRET = "bench-only-8c1d4f2a6b3e9d7c5a1f0e2d4c6b8a9f"
NEVER_CONVERGE = {
    "altitude_m": 1e-9,
    "longitude_deg": 1e-9,
    "latitude_deg": 1e-9,
    "flight_path_angle_deg": 1e-9,
    "heading_deg": 1e-9,
}
"""A stop tolerance no iterate meets: a job runs until its time limit."""
STRANDED_S = 30.0
"""No queued job may be stranded (unsent, or carried by no message) longer than this after the
recovery."""
STORED_RE = re.compile(r"job ([0-9a-f-]{36}): attempt (\d+) stored outcome (\w+)")
LOST_RE = re.compile(r"job [0-9a-f-]{36}: sent, still queued, and no queue message carries it")
"""The API's line for a job whose queue message was lost and that it sends again."""


def _percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    index = min(len(ordered) - 1, max(0, round(q * (len(ordered) - 1))))
    return ordered[index]


class Client(threading.Thread):
    """One API client: submits its jobs, then polls each until terminal, timing the reads."""

    def __init__(
        self, base_url: str, key: str, jobs: int, body: dict[str, Any], bound_s: float
    ) -> None:
        super().__init__(daemon=True)
        self.http = httpx.Client(base_url=base_url, timeout=60, headers={"X-API-Key": key})
        self.jobs, self.body, self.bound_s = jobs, body, bound_s
        self.ids: list[str] = []
        self.accepted_at: dict[str, float] = {}
        self.overdue: list[str] = []
        """Jobs not terminal within ``bound_s`` of their acceptance (no longer waited for)."""
        self.read_s: list[float] = []
        self.submit_s: list[float] = []
        self.refused: dict[int, int] = {}
        self.final: dict[str, str] = {}
        self.failed_requests = 0
        self.error: BaseException | None = None

    def run(self) -> None:
        try:
            self._run()
        except BaseException as exc:  # reported by the main thread
            self.error = exc

    def _run(self) -> None:
        while len(self.ids) < self.jobs:
            start = time.perf_counter()
            try:
                response = self.http.post("/v1/jobs", json=self.body)
            except httpx.TransportError:  # the API is down: not accepted, try again
                self.failed_requests += 1
                time.sleep(0.5)
                continue
            self.submit_s.append(time.perf_counter() - start)
            if response.status_code == 202:
                self.ids.append(response.json()["id"])
                self.accepted_at[self.ids[-1]] = time.monotonic()
            else:  # 429/503 are allowed answers under load: wait as told and retry
                self.refused[response.status_code] = self.refused.get(response.status_code, 0) + 1
                time.sleep(float(response.headers.get("retry-after", "1")))
        pending = list(self.ids)
        while pending:
            still: list[str] = []
            for job_id in pending:
                start = time.perf_counter()
                try:
                    response = self.http.get(f"/v1/jobs/{job_id}")
                except httpx.TransportError:
                    self.failed_requests += 1
                    still.append(job_id)
                    time.sleep(0.5)
                    continue
                if response.status_code >= 500:  # the database is away: read again later
                    self.failed_requests += 1
                    still.append(job_id)
                    continue
                self.read_s.append(time.perf_counter() - start)
                response.raise_for_status()
                status = response.json()["status"]
                if status in TERMINAL:
                    self.final[job_id] = status
                elif time.monotonic() - self.accepted_at[job_id] > self.bound_s:
                    self.overdue.append(job_id)  # reported with why at the end
                else:
                    still.append(job_id)
            pending = still
            time.sleep(0.2)
        self.http.close()


def _env(args: argparse.Namespace, logs: Path) -> tuple[dict[str, str], str]:
    import psycopg

    env = {k: v for k, v in os.environ.items() if not k.startswith("TRAJOPT_")}
    for name in ("DATABASE_URL", "REDIS_URL", "CELERY_BROKER_URL"):
        env.pop(name, None)
    schema = f"trajopt_load_{uuid.uuid4().hex[:10]}"
    with psycopg.connect(args.postgres_url, autocommit=True) as conn:
        conn.execute(f'CREATE SCHEMA "{schema}"')
    sep = "&" if "?" in args.postgres_url else "?"
    env.update(
        DATABASE_URL=f"{args.postgres_url}{sep}options={quote(f'-csearch_path={schema}')}",
        REDIS_URL=args.redis_url,
        TRAJOPT_QUEUE_NAME=f"trajopt-load-{uuid.uuid4().hex[:10]}",
        TRAJOPT_DATA_DIR=str(logs),
        TRAJOPT_AUTH_MODE="api-keys",
        TRAJOPT_API_KEY_SECRET=SECRET,
        TRAJOPT_RATE_SUBMIT_PER_WINDOW="0",
        TRAJOPT_RATE_READ_PER_WINDOW="0",
        TRAJOPT_MAX_ACTIVE_JOBS=str(args.jobs),
        TRAJOPT_LEASE_S=str(args.lease_s),
        TRAJOPT_SWEEP_INTERVAL_S="1",
    )
    return env, schema


def _create_key(env: dict[str, str], client: str) -> str:
    out = subprocess.run(
        [sys.executable, "-m", "app.cli", "keys", "create", "--client", client],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return out.stdout.strip()


def _check_database(database_url: str, ids: list[str]) -> dict[str, Any]:
    import psycopg

    with psycopg.connect(database_url) as conn:
        rows = conn.execute(
            "SELECT id, status, attempts, result IS NOT NULL, error_code FROM jobs",
        ).fetchall()
    by_id = {r[0]: r for r in rows}
    statuses: dict[str, int] = {}
    attempts: dict[int, int] = {}
    errors: dict[str, int] = {}
    for job_id in ids:
        row = by_id[job_id]
        statuses[row[1]] = statuses.get(row[1], 0) + 1
        attempts[row[2]] = attempts.get(row[2], 0) + 1
        errors[str(row[4])] = errors.get(str(row[4]), 0) + 1
    return {
        "rows": len(rows),
        "statuses": statuses,
        "error_codes": errors,
        "attempts": attempts,
        "succeeded_without_result": sum(1 for r in rows if r[1] == "succeeded" and not r[3]),
        "not_terminal": [r[0] for r in rows if r[1] not in TERMINAL],
        "worker_lost": [r[0] for r in rows if r[4] == "worker_lost"],
    }


def _through(proxy: TcpProxy, url: str) -> str:
    from sqlalchemy import make_url

    return make_url(url).set(host="127.0.0.1", port=proxy.port).render_as_string(False)


def _near_limit(database_url: str, ran_s: float) -> tuple[str, int] | None:
    """A job in its first attempt that has run ``ran_s`` or more, and its holder's pid."""
    import psycopg

    with psycopg.connect(database_url) as conn:
        row = conn.execute(
            "SELECT id, lease_holder FROM jobs WHERE status = 'running' AND attempts = 1 "
            "AND started_at <= now() - make_interval(secs => %s) LIMIT 1",
            (ran_s,),
        ).fetchone()
    if row is None or not row[1]:
        return None
    return str(row[0]), int(str(row[1]).rpartition("/")[2])


def _pool_pids(worker: _Process) -> set[int]:
    out = subprocess.run(["pgrep", "-P", str(worker.proc.pid)], capture_output=True, text=True)
    return {int(pid) for pid in out.stdout.split()}


def _job_row(database_url: str, job_id: str) -> dict[str, Any]:
    import psycopg

    with psycopg.connect(database_url) as conn:
        row = conn.execute(
            "SELECT status, attempts, error_code, error_message FROM jobs WHERE id = %s",
            (job_id,),
        ).fetchone()
    assert row is not None
    return dict(zip(("status", "attempts", "error_code", "error_message"), row, strict=True))


def _start_api(env: dict[str, str], port: int, log: Path) -> _Process:
    api = _Process(["serve", "--host", "127.0.0.1", "--port", str(port)], env, log)
    api.wait_for("Application startup complete", 90)
    return api


def run(args: argparse.Namespace, logs: Path) -> dict[str, Any]:
    """Run the scenario once and return the figures."""
    from sqlalchemy import make_url

    env, schema = _env(args, logs)
    direct_url = env["DATABASE_URL"]
    proxy: TcpProxy | None = None
    if args.fault == "database":
        upstream = make_url(direct_url)
        proxy = TcpProxy(upstream.host or "127.0.0.1", upstream.port or 5432)
        proxy.start()
        env["DATABASE_URL"] = _through(proxy, direct_url)
    processes: list[_Process] = []
    method: dict[str, Any] = {"nodes": args.nodes, "max_iterations": args.max_iterations}
    if args.fault == "near-limit":  # jobs that iterate until their own time limit ends them
        method = {"nodes": 200, "max_iterations": 500, "time_limit_s": args.job_time_limit_s,
                  "stop_tolerance": NEVER_CONVERGE}  # fmt: skip
    body = {"scenario": args.scenario, "method": method}
    victim: str | None = None
    monitor: StrandMonitor | None = None
    try:
        keys = [_create_key(env, f"client-{i}") for i in range(args.clients)]
        port = _free_port()
        api = _start_api(env, port, logs / "api.log")
        processes.append(api)
        workers = []
        for index in range(2):
            worker = _Process(["worker", "--concurrency", "1"], env, logs / f"worker-{index}.log")
            processes.append(worker)
            worker.wait_for(" ready.", 90)
            workers.append(worker)
        base_url = f"http://127.0.0.1:{port}"
        share = [args.jobs // args.clients + (i < args.jobs % args.clients)
                 for i in range(args.clients)]  # fmt: skip
        clients = [
            Client(base_url, k, n, body, args.job_bound_s) for k, n in zip(keys, share, strict=True)
        ]
        start = time.perf_counter()
        for c in clients:
            c.start()
        fault_at = recovered_at = None
        while any(c.is_alive() for c in clients):
            done = sum(len(c.final) for c in clients)
            accepted_now = sum(len(c.ids) for c in clients)
            due = (
                accepted_now >= args.kill_after if args.fault == "api" else done >= args.kill_after
            )
            if args.fault == "near-limit" and fault_at is None:
                found = _near_limit(direct_url, 0.6 * args.job_time_limit_s)
                due = found is not None
                if found is not None:
                    victim, holder = found
                    workers = [w for w in workers if holder in _pool_pids(w)] + [
                        w for w in workers if holder not in _pool_pids(w)
                    ]  # the worker running the victim first
            if fault_at is None and due:
                fault_at = time.perf_counter() - start
                if args.fault in ("worker", "near-limit"):
                    os.killpg(workers[0].proc.pid, signal.SIGKILL)  # main process and pool child
                    workers[0].proc.wait()
                    time.sleep(args.restart_after_s)
                    replacement = _Process(["worker", "--concurrency", "1"], env,
                                           logs / "worker-0-restarted.log")  # fmt: skip
                    processes.append(replacement)
                    replacement.wait_for(" ready.", 90)
                elif args.fault == "api":
                    os.killpg(api.proc.pid, signal.SIGKILL)  # between commits and sends
                    api.proc.wait()
                    time.sleep(args.restart_after_s)
                    api = _start_api(env, port, logs / "api-restarted.log")
                    processes.append(api)
                else:
                    assert proxy is not None
                    proxy.cut()
                    time.sleep(args.outage_s)
                    proxy.restore()
                recovered_at = time.perf_counter() - start
                monitor = StrandMonitor(
                    direct_url, args.redis_url, env["TRAJOPT_QUEUE_NAME"], args.lease_s,
                    STRANDED_S,
                )  # fmt: skip
                monitor.start()
            time.sleep(0.2)
        wall = time.perf_counter() - start
        if monitor is not None:
            monitor.stop()
        for c in clients:
            if c.error is not None:
                raise RuntimeError(f"a client failed: {c.error!r}")
        ids = [job_id for c in clients for job_id in c.ids]
        database = _check_database(direct_url, ids)
        overdue = [job_id for c in clients for job_id in c.overdue]
        unfinished = sorted(set(overdue) | set(database["not_terminal"]))
        why = explain(direct_url, args.redis_url, env["TRAJOPT_QUEUE_NAME"], unfinished)
        worker_logs = "\n".join(
            p.log.read_text(errors="replace") for p in processes if "worker" in p.log.name
        )
        api_logs = "\n".join(
            p.log.read_text(errors="replace") for p in processes if "api" in p.log.name
        )
        stored: dict[str, int] = {}
        for match in STORED_RE.finditer(worker_logs):
            stored[match.group(1)] = stored.get(match.group(1), 0) + 1
        reads = [s for c in clients for s in c.read_s]
        submits = [s for c in clients for s in c.submit_s]
        lost = set(database["worker_lost"])
        return {
            "fault": args.fault,
            "job": body,
            "clients": args.clients,
            "accepted": len(ids),
            "distinct_ids": len(set(ids)),
            "terminal_by_client_view": sum(len(c.final) for c in clients),
            "database": {k: v for k, v in database.items() if k != "worker_lost"},
            "worker_lost": len(lost),
            "stored_outcomes_max_per_job": max(stored.values()) if stored else 0,
            "jobs_stored_once": sum(1 for j in ids if stored.get(j) == 1),
            "jobs_stored_twice_or_more": sum(1 for j in ids if stored.get(j, 0) > 1),
            "jobs_without_stored_outcome": sorted(j for j in ids if j not in stored),
            "refused_submissions": {
                str(k): sum(c.refused.get(k, 0) for c in clients) for k in (429, 503)
            },
            "failed_requests": sum(c.failed_requests for c in clients),
            "fault_at_s": fault_at,
            "recovered_at_s": recovered_at,
            "max_stranded_after_recovery_s": monitor.max_stranded_s if monitor else None,
            "stranded_over_bound": monitor.over_bound if monitor else {},
            "job_bound_s": args.job_bound_s,
            "not_terminal_within_bound": {j: why.get(j, "terminal late") for j in overdue},
            "not_terminal_at_the_end": {j: why.get(j, "?") for j in database["not_terminal"]},
            "near_limit_job": _job_row(direct_url, victim) if victim else None,
            "lost_messages_resent": len(LOST_RE.findall(api_logs)),
            "wall_s": wall,
            "status_reads": len(reads),
            "status_read_p50_ms": 1e3 * statistics.median(reads),
            "status_read_p95_ms": 1e3 * _percentile(reads, 0.95),
            "status_read_max_ms": 1e3 * max(reads),
            "submit_p95_ms": 1e3 * _percentile(submits, 0.95),
        }
    finally:
        for process in reversed(processes):
            process.stop()
        if proxy is not None:
            proxy.cut()
        _cleanup(args, env, schema)


def _cleanup(args: argparse.Namespace, env: dict[str, str], schema: str) -> None:
    import psycopg
    import redis

    with psycopg.connect(args.postgres_url, autocommit=True) as conn:
        conn.execute(f'DROP SCHEMA IF EXISTS "{schema}" CASCADE')
    queue = env["TRAJOPT_QUEUE_NAME"]
    client = redis.Redis.from_url(args.redis_url)
    bindings = (f"_kombu.binding.{queue}", f"_kombu.binding_permanent.{queue}")
    client.delete(*priority_lists(queue), *bindings)
    for key in client.scan_iter(f"trajopt:rate:{queue}:*"):
        client.delete(key)
    client.close()


def parser() -> argparse.ArgumentParser:
    """main()'s argument parser, apart so a test checks the documented commands against it."""
    cli = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cli.add_argument("--jobs", type=int, default=200)
    cli.add_argument("--clients", type=int, default=4)
    cli.add_argument("--scenario", default="rlv-min-heat-load")
    cli.add_argument("--nodes", type=int, default=41)
    cli.add_argument("--max-iterations", type=int, default=8)
    cli.add_argument("--kill-after", type=int, default=20,
                     help="kill worker 1 once this many jobs are terminal")  # fmt: skip
    cli.add_argument("--restart-after-s", type=float, default=3.0)
    cli.add_argument("--fault", choices=("worker", "api", "database", "near-limit"),
                     default="worker", help="what is lost: a worker, the API, the database, "
                     "or a worker whose job has run 60 %% of its time limit")  # fmt: skip
    cli.add_argument("--job-time-limit-s", type=float, default=6.0,
                     help="time limit of each job (--fault near-limit)")  # fmt: skip
    cli.add_argument("--outage-s", type=float, default=20.0,
                     help="how long the database is unreachable (--fault database)")  # fmt: skip
    cli.add_argument("--lease-s", type=float, default=10.0)
    cli.add_argument("--job-bound-s", type=float, default=300.0,
                     help="every job must be terminal this long after its acceptance; the "
                     "clients stop waiting for one that is not, and the run fails")  # fmt: skip
    add_stack_arguments(cli, redis_db=12)
    return cli


def main(argv: list[str] | None = None) -> int:
    """Run the load test, print the figures, and exit 1 if any guarantee was broken."""
    args = parser().parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="trajopt-load-") as tmp:
        report = run(args, Path(tmp))
    print(json.dumps(report, indent=2))
    if args.output:
        args.output.write_text(json.dumps(report, indent=2) + "\n")
    problems = _broken_guarantees(report, args)
    db = report["database"]
    print("PASS" if not problems else "FAIL", f"- {report['accepted']} accepted, "
          f"{sum(n for k, n in db['statuses'].items() if k in TERMINAL)} terminal "
          f"{db['statuses']}, "
          f"p95 status read {report['status_read_p95_ms']:.1f} ms")  # fmt: skip
    for problem in problems:
        print(f"  {problem}")
    return 0 if not problems else 1


def _broken_guarantees(report: dict[str, Any], args: argparse.Namespace) -> list[str]:
    """One line per guarantee the run broke (job by job where it is about jobs)."""
    db = report["database"]
    problems: list[str] = []
    if not report["accepted"] == args.jobs == report["distinct_ids"]:
        problems.append(f"{report['accepted']} accepted, {report['distinct_ids']} distinct ids")
    if db["rows"] < args.jobs:  # more: stored, but the answer died with the API
        problems.append(f"only {db['rows']} rows in the database")
    for job_id, why in report["not_terminal_within_bound"].items():
        problems.append(f"job {job_id} not terminal within {args.job_bound_s:g} s: {why}")
    for job_id, why in report["not_terminal_at_the_end"].items():
        problems.append(f"job {job_id} not terminal at the end: {why}")
    for job_id, why in report["stranded_over_bound"].items():
        problems.append(f"job {job_id} stranded after the recovery: {why}")
    if report["jobs_stored_twice_or_more"]:
        problems.append(f"{report['jobs_stored_twice_or_more']} job(s) stored twice or more")
    if db["succeeded_without_result"]:
        problems.append(f"{db['succeeded_without_result']} succeeded job(s) without a result")
    near = report["near_limit_job"]
    if args.fault == "near-limit":  # retried, and ended by its own limit, not the sweeper's
        if near is None or near["attempts"] != 2:
            problems.append(f"the near-limit victim did not get exactly 2 attempts: {near}")
        elif "stopped answering" in str(near["error_message"]):
            problems.append(f"the near-limit victim was ended by the sweeper: {near}")
    return problems


if __name__ == "__main__":
    sys.exit(main())
