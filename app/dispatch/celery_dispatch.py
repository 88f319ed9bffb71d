"""Dispatch through Celery: publish the job id on the Redis queue with the job's time limits,
and tell which jobs a message still carries (for the sweeper's lost-message check)."""

from __future__ import annotations

import itertools
import json
import time
from collections.abc import Collection, Iterable
from typing import Any

import redis

from app.settings import Settings
from worker.celery_app import (
    CLAIM_RETRY_MAX_S,
    TASK_NAME,
    UNACKED_INDEX_KEY,
    UNACKED_KEY,
    create_celery,
    priority_lists,
)
from worker.limits import TimeLimits


class CeleryDispatcher:
    """Publishes ``trajopt.solve_job`` messages; workers run anywhere against the same Redis."""

    kind = "celery"

    def __init__(self, settings: Settings) -> None:
        self._settings = settings
        self._celery = create_celery(settings)
        self._redis = redis.Redis.from_url(
            settings.broker_url,
            socket_timeout=settings.request_timeout_s,
            socket_connect_timeout=settings.request_timeout_s,
        )

    def start(self) -> None:
        """Nothing to prepare: connections open on first use."""

    def submit(self, job_id: str, limits: TimeLimits, priority: int = 0) -> None:
        """Publish the job with its soft and hard time limits (the job id is the task id) on
        the priority list of ``priority``."""
        self._celery.send_task(
            TASK_NAME,
            args=[job_id],
            task_id=job_id,
            queue=self._settings.queue_name,
            soft_time_limit=limits.soft_s,
            time_limit=limits.hard_s,
            priority=priority,
        )

    def carried(self, job_ids: Collection[str]) -> set[str] | None:
        """Which of ``job_ids`` a message still carries: one waiting in a priority list of
        the queue, or one delivered to a worker (kombu's ``unacked`` hash) no longer ago than
        a worker takes to claim its job (a lease, plus the claim's retry back-off). A message
        delivered longer ago to a job still queued lies with a worker that died before it
        claimed the job. One atomic read of Redis (MULTI/EXEC): a message moving from a list to
        the hash is seen in one or the other. ``None`` when Redis cannot be read."""
        wanted = set(job_ids)
        try:
            with self._redis.pipeline(transaction=True) as pipe:
                for name in priority_lists(self._settings.queue_name):
                    pipe.lrange(name, 0, -1)
                pipe.hgetall(UNACKED_KEY)
                pipe.zrange(UNACKED_INDEX_KEY, 0, -1, withscores=True)
                *waiting, unacked, delivered_at = pipe.execute()
        except redis.RedisError:
            return None
        fresh_after = time.time() - (self._settings.lease_s + CLAIM_RETRY_MAX_S)
        delivered = {_text(tag): float(at) for tag, at in delivered_at}
        in_flight = (
            _unacked_message(raw)
            for tag, raw in unacked.items()
            if delivered.get(_text(tag), 0.0) >= fresh_after
        )
        messages: Iterable[Any] = itertools.chain(
            (_loads(raw) for raw in itertools.chain.from_iterable(waiting)), in_flight
        )
        return {job_id for job_id in map(_task_id, messages) if job_id in wanted}

    def ping(self) -> str | None:
        """``None`` when Redis answers PING."""
        try:
            self._redis.ping()
        except redis.RedisError as exc:
            return f"broker unreachable: {type(exc).__name__}: {exc}"
        return None

    def queue_depth(self) -> int | None:
        """Messages waiting in the Redis lists of the queue's priorities (not reserved ones)."""
        try:
            with self._redis.pipeline() as pipe:
                for name in priority_lists(self._settings.queue_name):
                    pipe.llen(name)
                return sum(int(n) for n in pipe.execute())
        except redis.RedisError:
            return None

    def shutdown(self) -> None:
        """Close the broker connections."""
        self._redis.close()
        self._celery.close()


def _text(value: Any) -> str:
    return value.decode("utf-8", "replace") if isinstance(value, bytes) else str(value)


def _loads(raw: Any) -> Any:
    try:
        return json.loads(raw)
    except ValueError:
        return None


def _unacked_message(raw: Any) -> Any:
    """The message of an ``unacked`` entry (``[message, exchange, routing key]``)."""
    entry = _loads(raw)
    return entry[0] if isinstance(entry, list) and entry else None


def _task_id(message: Any) -> str | None:
    """The task id of a kombu message (Celery's protocol 2 puts it in the headers)."""
    if not isinstance(message, dict):
        return None
    headers = message.get("headers")
    if isinstance(headers, dict) and isinstance(headers.get("id"), str):
        return str(headers["id"])
    properties = message.get("properties")
    if isinstance(properties, dict) and isinstance(properties.get("correlation_id"), str):
        return str(properties["correlation_id"])
    return None
