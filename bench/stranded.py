"""Queued jobs that nothing will run: what bench.load_faults watches for, by its own reads.

A queued job is *stranded* while it is due in the outbox and nobody sends it, or while it is
marked sent and no message carries it: none waits in the queue's Redis lists, and none was
delivered to a worker (kombu's ``unacked`` hash) within a lease, plus the 10 s back-off of a
claim that found the database away, of now (a worker claims its job as soon as it gets its
message, so an older delivery of a job still queued lies with a worker that died). These reads
are the benchmark's own, independent of the service's checks.
"""

from __future__ import annotations

import json
import threading
import time
from typing import Any

import redis

from worker.celery_app import priority_lists

UNACKED, UNACKED_INDEX = "unacked", "unacked_index"
"""kombu's Redis keys of the messages delivered to a worker and not yet acknowledged."""
CLAIM_BACKOFF_S = 10.0
"""Longest wait of a delivered message whose claim found the database away."""


def _task_id(message: Any) -> str | None:
    headers = message.get("headers") if isinstance(message, dict) else None
    return str(headers["id"]) if isinstance(headers, dict) and "id" in headers else None


def where_messages_are(redis_url: str, queue: str) -> dict[str, tuple[str, float]]:
    """For each job a message names: ``("waiting", 0)`` if one waits in the queue's lists,
    else ``("delivered", seconds ago)`` of its latest delivery to a worker (one atomic read)."""
    client = redis.Redis.from_url(redis_url)
    try:
        with client.pipeline(transaction=True) as pipe:
            for name in priority_lists(queue):
                pipe.lrange(name, 0, -1)
            pipe.hgetall(UNACKED)
            pipe.zrange(UNACKED_INDEX, 0, -1, withscores=True)
            *lists, unacked, index = pipe.execute()
    finally:
        client.close()
    now = time.time()
    delivered_at = {tag: at for tag, at in index}
    found: dict[str, tuple[str, float]] = {}
    for tag, raw in unacked.items():
        entry = json.loads(raw)
        job_id = _task_id(entry[0] if isinstance(entry, list) and entry else None)
        if job_id is not None:
            age = now - float(delivered_at.get(tag, 0.0))
            if job_id not in found or age < found[job_id][1]:
                found[job_id] = ("delivered", age)
    for raw in (item for items in lists for item in items):
        job_id = _task_id(json.loads(raw))
        if job_id is not None:
            found[job_id] = ("waiting", 0.0)
    return found


def stranded_reason(
    due_age_s: float | None, message: tuple[str, float] | None, fresh_s: float
) -> str | None:
    """Why a queued job is stranded (None if something will run it): ``due_age_s`` is how
    long it has been due in the outbox (None when sent; negative while a sender holds it)."""
    if due_age_s is not None:
        return f"due in the outbox for {due_age_s:.0f} s, unsent" if due_age_s > 0 else None
    if message is None:
        return "marked sent, and no message in the queue or delivered to a worker"
    where, age = message
    if where == "delivered" and age > fresh_s:
        return f"marked sent; its message was delivered {age:.0f} s ago and never claimed"
    return None


class StrandMonitor(threading.Thread):
    """Samples every half second, from the recovery on, how long each queued job has been
    stranded; keeps the longest and every job stranded longer than ``bound_s``, with why."""

    def __init__(
        self, database_url: str, redis_url: str, queue: str, lease_s: float, bound_s: float
    ) -> None:
        super().__init__(daemon=True)
        self.url, self.redis_url, self.queue = database_url, redis_url, queue
        self.fresh_s = lease_s + CLAIM_BACKOFF_S
        self.bound_s = bound_s
        self.max_stranded_s = 0.0
        self.over_bound: dict[str, str] = {}
        self.samples = 0
        self._since: dict[str, float] = {}
        self._done = threading.Event()

    def run(self) -> None:
        import psycopg

        with psycopg.connect(self.url, autocommit=True) as conn:
            while not self._done.wait(0.5):
                rows = conn.execute(
                    "SELECT id, extract(epoch FROM now() - dispatch_due_at) FROM jobs "
                    "WHERE status = 'queued'"
                ).fetchall()
                messages = where_messages_are(self.redis_url, self.queue)
                self._sample(rows, messages, time.monotonic())

    def _sample(self, rows: list[Any], messages: dict[str, tuple[str, float]], now: float) -> None:
        self.samples += 1
        stranded: dict[str, float] = {}
        for job_id, due_age in rows:
            due = None if due_age is None else float(due_age)
            reason = stranded_reason(due, messages.get(job_id), self.fresh_s)
            if reason is None:
                continue
            stranded[job_id] = self._since.get(job_id, now)
            lasted = now - stranded[job_id]
            self.max_stranded_s = max(self.max_stranded_s, lasted)
            if lasted > self.bound_s:
                self.over_bound[job_id] = f"{reason} ({lasted:.0f} s stranded)"
        self._since = stranded

    def stop(self) -> None:
        """Stop sampling."""
        self._done.set()
        self.join(timeout=5)


def explain(database_url: str, redis_url: str, queue: str, ids: list[str]) -> dict[str, str]:
    """For each of ``ids`` not terminal: its status, attempts and where its message is."""
    import psycopg

    with psycopg.connect(database_url) as conn:
        rows = conn.execute(
            "SELECT id, status, attempts, dispatch_due_at IS NULL, "
            "extract(epoch FROM now() - updated_at) FROM jobs WHERE id = ANY(%s) "
            "AND status IN ('queued', 'running')",
            (ids,),
        ).fetchall()
    messages = where_messages_are(redis_url, queue)
    why: dict[str, str] = {}
    for job_id, status, attempts, sent, idle in rows:
        where, age = messages.get(job_id, ("nowhere", 0.0))
        message = f"message {where}" + (f" {age:.0f} s ago" if where == "delivered" else "")
        why[job_id] = (
            f"{status}, attempts {attempts}, {'marked sent' if sent else 'due, unsent'}, "
            f"{message}, unchanged for {float(idle):.0f} s"
        )
    return why
