"""``trajopt worker``: migrate the database, then run a Celery worker on the configured queue."""

from __future__ import annotations

import os

from app.settings import get_settings
from app.storage.migrate import upgrade_database
from app.storage.session import dispose_all, get_database
from worker.limits import check_visibility_timeout


def worker_argv(concurrency: int | None, queue: str, node_name: str) -> list[str]:
    """Command-line arguments of the Celery worker."""
    argv = [
        "worker",
        "--loglevel=INFO",
        f"--queues={queue}",
        f"--hostname={node_name.replace('{pid}', str(os.getpid()))}",
        "--without-gossip",
        "--without-mingle",
    ]
    if concurrency is not None:
        argv.append(f"--concurrency={concurrency}")
    return argv


def run_worker(concurrency: int | None = None) -> None:
    """Run a worker until stopped; exits with a message when no broker is configured."""
    settings = get_settings()
    if not settings.uses_broker:
        raise SystemExit(
            "no broker configured: set REDIS_URL (or TRAJOPT_BROKER_URL) to run separate "
            "workers; without one, `trajopt serve` runs jobs in its own process pool"
        )
    try:
        check_visibility_timeout(settings)
    except ValueError as exc:
        raise SystemExit(f"refusing to start: {exc}") from None
    if settings.auto_migrate:
        upgrade_database(get_database(settings.effective_database_url).engine)
    dispose_all()  # the pool's children open their own connections

    from worker.tasks import app

    app.worker_main(worker_argv(concurrency, settings.queue_name, settings.worker_node_name))
