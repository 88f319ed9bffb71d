"""Dispatch through Celery: publish the job id on the Redis queue with the job's time limits."""

from __future__ import annotations

import redis

from app.settings import Settings
from worker.celery_app import TASK_NAME, create_celery, priority_lists
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
