"""The Celery task: a thin wrapper that hands the job id to :func:`worker.jobs.execute_job`."""

from __future__ import annotations

from functools import cache

from celery.exceptions import SoftTimeLimitExceeded
from sqlalchemy.exc import InterfaceError, OperationalError

from app.settings import get_settings
from worker.celery_app import CLAIM_RETRY_MAX_S, TASK_NAME, app
from worker.jobs import execute_job
from worker.notify import RedisNotifier
from worker.solver import api as _solver_api  # noqa: F401  (loaded once, before the pool forks)
from worker.solver.warmup import warm_up

warm_up()  # the compiled kernels too, before the pool forks: no job pays for their compilation


@cache
def _notifier(url: str) -> RedisNotifier:
    return RedisNotifier(url)


@app.task(
    name=TASK_NAME,
    acks_late=True,
    reject_on_worker_lost=True,
    ignore_result=True,
    autoretry_for=(OperationalError, InterfaceError),
    retry_backoff=1,
    retry_backoff_max=CLAIM_RETRY_MAX_S,
    max_retries=None,
)
def solve_job(job_id: str) -> str:
    """Run the stored job ``job_id``; duplicate deliveries of a finished job do nothing.

    A database that cannot be reached is retried with backoff (at most 10 s apart, for as long
    as the outage lasts, so the job runs within seconds of the database's return); a retry is a
    new delivery, so the attempt counter still bounds how often the solve itself restarts.
    """
    settings = get_settings()
    return execute_job(
        job_id,
        settings=settings,
        timeout_exceptions=(SoftTimeLimitExceeded,),
        notify=_notifier(settings.broker_url),
        kill_stuck_solve=True,
    )
