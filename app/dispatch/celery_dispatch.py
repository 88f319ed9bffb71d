"""Dispatch through Celery: publish the job id on the Redis queue with the job's time limits."""

from __future__ import annotations

import redis

from app.settings import Settings
from worker.celery_app import TASK_NAME, create_celery
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

    def submit(self, job_id: str, limits: TimeLimits) -> None:
        """Publish the job with its soft and hard time limits (the job id is the task id)."""
        self._celery.send_task(
            TASK_NAME,
            args=[job_id],
            task_id=job_id,
            queue=self._settings.queue_name,
            soft_time_limit=limits.soft_s,
            time_limit=limits.hard_s,
        )

    def ping(self) -> str | None:
        """``None`` when Redis answers PING."""
        try:
            self._redis.ping()
        except redis.RedisError as exc:
            return f"broker unreachable: {type(exc).__name__}: {exc}"
        return None

    def queue_depth(self) -> int | None:
        """Messages waiting in the Redis list of the queue (not counting reserved ones)."""
        try:
            return int(self._redis.llen(self._settings.queue_name))
        except redis.RedisError:
            return None

    def shutdown(self) -> None:
        """Close the broker connections."""
        self._redis.close()
        self._celery.close()
