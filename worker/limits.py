"""Per-job time limits: the job's own option, capped by the server, plus the Celery margins.

The solver stops itself at ``solve_s``; the Celery soft limit (``soft_s``) is a backstop for a
single conic solve that never returns, and the hard limit (``hard_s``) kills the process.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from app.settings import Settings


@dataclass(frozen=True)
class TimeLimits:
    """Deadlines of one job in seconds from its start."""

    solve_s: float
    soft_s: float
    hard_s: float


def requested_time_limit(problem: dict[str, Any]) -> float | None:
    """The ``method.time_limit_s`` option of a problem document, if it sets one."""
    method = problem.get("method")
    if isinstance(method, dict):
        value = method.get("time_limit_s")
        if isinstance(value, int | float) and not isinstance(value, bool) and value > 0:
            return float(value)
    return None


def job_time_limits(problem: dict[str, Any], settings: Settings) -> TimeLimits:
    """Limits for a job: its ``time_limit_s`` (else the server default), capped by the server."""
    requested = requested_time_limit(problem)
    solve_s = min(
        requested if requested is not None else settings.default_time_limit_s,
        settings.max_time_limit_s,
    )
    soft_s = solve_s + settings.soft_limit_margin_s
    return TimeLimits(solve_s=solve_s, soft_s=soft_s, hard_s=soft_s + settings.hard_limit_grace_s)


def check_visibility_timeout(settings: Settings) -> None:
    """Refuse to start when a redelivery could happen while a job may still legally run."""
    if settings.visibility_timeout_s <= settings.max_hard_limit_s:
        raise ValueError(
            f"TRAJOPT_VISIBILITY_TIMEOUT_S={settings.visibility_timeout_s:g} must exceed the "
            f"longest hard time limit {settings.max_hard_limit_s:g} s "
            "(max_time_limit_s + soft_limit_margin_s + hard_limit_grace_s); otherwise Redis "
            "would hand a still-running job to a second worker"
        )
