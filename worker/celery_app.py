"""The Celery application: Redis broker, JSON only, late acknowledgement, one task at a time.

Built from the same settings as the API; refuses to start when Redis could redeliver a job that
may still be running (visibility timeout not above the longest hard time limit).
"""

from __future__ import annotations

from typing import Any

from celery import Celery

from app.settings import Settings, get_settings
from worker.limits import check_visibility_timeout

TASK_NAME = "trajopt.solve_job"
PRIORITY_LEVELS = 10
"""Message priorities 0 (first) to 9: Redis keeps one list per level, ``queue`` for 0 and
``queue:N`` for N, and workers pop the lowest non-empty level first."""


CLAIM_RETRY_MAX_S = 10
"""Longest back-off of a task that could not claim its job (the database unreachable): its
message is held, delivered, for at most this long before the task runs again."""
UNACKED_KEY = "unacked"
UNACKED_INDEX_KEY = "unacked_index"
"""kombu's Redis keys of the messages delivered to a worker and not yet acknowledged: a hash
of delivery tag -> ``[message, exchange, routing key]`` and a sorted set of delivery tag ->
delivery time (kombu's defaults, which this configuration keeps)."""


def priority_lists(queue: str) -> list[str]:
    """The Redis lists holding ``queue``'s messages, highest priority first."""
    return [queue, *(f"{queue}:{level}" for level in range(1, PRIORITY_LEVELS))]


def celery_config(settings: Settings) -> dict[str, Any]:
    """The Celery configuration derived from ``settings``."""
    check_visibility_timeout(settings)
    return {
        "broker_url": settings.broker_url or "memory://",
        "broker_connection_retry_on_startup": True,
        "broker_transport_options": {
            "visibility_timeout": int(settings.visibility_timeout_s),
            "priority_steps": list(range(PRIORITY_LEVELS)),
            "sep": ":",
            "queue_order_strategy": "priority",
        },
        "task_default_priority": 0,
        "task_serializer": "json",
        "accept_content": ["json"],
        "result_serializer": "json",
        "result_accept_content": ["json"],
        "task_ignore_result": True,
        "task_store_errors_even_if_ignored": False,
        "task_acks_late": True,
        "task_reject_on_worker_lost": True,
        "task_default_queue": settings.queue_name,
        "task_soft_time_limit": settings.max_time_limit_s + settings.soft_limit_margin_s,
        "task_time_limit": settings.max_hard_limit_s,
        "worker_prefetch_multiplier": 1,
        "worker_max_tasks_per_child": settings.worker_max_tasks_per_child,
        "worker_cancel_long_running_tasks_on_connection_loss": True,
        "worker_send_task_events": False,
        "worker_hijack_root_logger": False,
        "enable_utc": True,
        "timezone": "UTC",
    }


def create_celery(settings: Settings | None = None) -> Celery:
    """A configured Celery app (tasks are registered by importing :mod:`worker.tasks`)."""
    app = Celery("trajopt")
    app.conf.update(celery_config(settings or get_settings()))
    return app


app = create_celery()
