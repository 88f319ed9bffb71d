"""Per-job time limits: the job's own option, capped by the server, plus the Celery margins.

A job's ``method.time_limit_s`` is CPU time, which the solver measures and stops itself at
(``worker.solver.solve_clock``); the job's wall-clock limit ``solve_s`` is ``WALL_FACTOR``
times it (at most the server's cap), so a loaded machine does not decide the answer but a
starved one still ends the job. The worker stops the solve at ``solve_s``; the Celery soft
limit (``soft_s``) is a backstop for a single conic solve that never returns; a solve that
ignores even that is ended at ``stuck_s`` by the worker's watchdog (:mod:`worker.watchdog`).
Celery's hard limit (``hard_s``) kills the process: it adds the time an attempt may hold its
finished result while the database is away (``result_write_retry_s``), so a short job's held
result is not lost to it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from app.settings import Settings
from worker.solver.solve_clock import WALL_FACTOR


@dataclass(frozen=True)
class TimeLimits:
    """Deadlines of one job in seconds from its start."""

    cpu_s: float | None
    """The job's CPU-time limit (its ``time_limit_s``; None when it sets none: its method's own
    default then bounds the optimization), which the worker also holds the verification to."""
    solve_s: float
    """The job's wall-clock limit: the worker stops the solve (its CPU-time limit, which the
    solver keeps itself, times ``WALL_FACTOR``, at most the server's cap)."""
    soft_s: float
    """Celery raises its soft limit into a solve still running."""
    stuck_s: float
    """The worker's watchdog ends the process of a solve still running."""
    hard_s: float
    """Celery kills the process: ``stuck_s`` plus the hold of a finished result."""


def requested_time_limit(problem: dict[str, Any]) -> float | None:
    """The ``method.time_limit_s`` option of a problem document, if it sets one."""
    method = problem.get("method")
    if isinstance(method, dict):
        value = method.get("time_limit_s")
        if isinstance(value, int | float) and not isinstance(value, bool) and value > 0:
            return float(value)
    return None


def job_time_limits(problem: dict[str, Any], settings: Settings) -> TimeLimits:
    """Limits for a job: ``WALL_FACTOR`` x its CPU ``time_limit_s``, or the server default when
    it sets none, capped by the server."""
    requested = requested_time_limit(problem)
    cpu_s = None if requested is None else min(requested, settings.max_time_limit_s)
    solve_s = min(
        WALL_FACTOR * cpu_s if cpu_s is not None else settings.default_time_limit_s,
        settings.max_time_limit_s,
    )
    soft_s = solve_s + settings.soft_limit_margin_s
    stuck_s = soft_s + settings.hard_limit_grace_s
    hard_s = stuck_s + settings.result_write_retry_s
    return TimeLimits(cpu_s=cpu_s, solve_s=solve_s, soft_s=soft_s, stuck_s=stuck_s, hard_s=hard_s)


def check_visibility_timeout(settings: Settings) -> None:
    """Refuse to start when a redelivery could happen while a job may still legally run."""
    if settings.visibility_timeout_s <= settings.max_hard_limit_s:
        raise ValueError(
            f"TRAJOPT_VISIBILITY_TIMEOUT_S={settings.visibility_timeout_s:g} must exceed the "
            f"longest hard time limit {settings.max_hard_limit_s:g} s "
            "(max_time_limit_s + soft_limit_margin_s + hard_limit_grace_s + "
            "result_write_retry_s); otherwise Redis "
            "would hand a still-running job to a second worker"
        )
