"""Settings, time limits and the Celery configuration of the service."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from app.settings import Settings, default_local_workers, normalize_database_url
from worker.celery_app import celery_config
from worker.limits import check_visibility_timeout, job_time_limits, requested_time_limit


def test_embedded_defaults_use_sqlite_in_data_dir_and_no_broker(tmp_path: Path) -> None:
    settings = Settings(data_dir=tmp_path, database_url="", broker_url="")
    assert settings.effective_database_url == f"sqlite:///{tmp_path.as_posix()}/trajopt.sqlite3"
    assert not settings.uses_broker


def test_environment_names(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DATABASE_URL", "postgresql://u@db:5432/trajopt")
    monkeypatch.setenv("REDIS_URL", "redis://redis:6379/0")
    monkeypatch.setenv("TRAJOPT_MAX_ATTEMPTS", "5")
    settings = Settings()
    assert settings.effective_database_url == "postgresql+psycopg://u@db:5432/trajopt"
    assert settings.broker_url == "redis://redis:6379/0"
    assert settings.uses_broker
    assert settings.max_attempts == 5


@pytest.mark.parametrize(
    ("given", "expected"),
    [
        ("postgres://a@b/c", "postgresql+psycopg://a@b/c"),
        ("postgresql://a@b/c", "postgresql+psycopg://a@b/c"),
        ("postgresql+psycopg://a@b/c", "postgresql+psycopg://a@b/c"),
        ("sqlite:///x.db", "sqlite:///x.db"),
    ],
)
def test_database_url_driver(given: str, expected: str) -> None:
    assert normalize_database_url(given) == expected


def test_time_limits_follow_the_job_and_are_capped() -> None:
    settings = Settings(
        max_time_limit_s=100,
        default_time_limit_s=50,
        soft_limit_margin_s=5,
        hard_limit_grace_s=10,
        result_write_retry_s=200,
    )
    # 20 CPU seconds: a wall-clock limit four times as long
    own = job_time_limits({"method": {"time_limit_s": 20}}, settings)
    assert (own.cpu_s, own.solve_s, own.soft_s, own.stuck_s, own.hard_s) == (20, 80, 85, 95, 295)
    capped = job_time_limits({"method": {"time_limit_s": 1000}}, settings)
    assert (capped.cpu_s, capped.solve_s, capped.soft_s) == (100, 100, 105)
    assert (capped.stuck_s, capped.hard_s) == (115, 315)
    assert capped.hard_s == settings.max_hard_limit_s  # the result's hold is inside the limit
    default = job_time_limits({"method": {}}, settings)
    assert (default.cpu_s, default.solve_s) == (None, 50)
    assert requested_time_limit({"method": {"time_limit_s": True}}) is None


def test_visibility_timeout_must_exceed_the_longest_hard_limit() -> None:
    ok = Settings(max_time_limit_s=100, visibility_timeout_s=1000)
    check_visibility_timeout(ok)
    bad = Settings(
        max_time_limit_s=100, soft_limit_margin_s=5, hard_limit_grace_s=10, visibility_timeout_s=115
    )
    with pytest.raises(ValueError, match="VISIBILITY_TIMEOUT"):
        check_visibility_timeout(bad)
    with pytest.raises(ValueError):
        celery_config(bad)


def test_celery_configuration_is_safe_for_long_cpu_jobs() -> None:
    settings = Settings(broker_url="redis://localhost:6379/3", queue_name="q1")
    conf = celery_config(settings)
    assert conf["accept_content"] == ["json"]
    assert conf["task_serializer"] == "json"
    assert conf["task_acks_late"] is True
    assert conf["task_reject_on_worker_lost"] is True
    assert conf["worker_prefetch_multiplier"] == 1
    assert conf["worker_cancel_long_running_tasks_on_connection_loss"] is True
    assert conf["worker_max_tasks_per_child"] == settings.worker_max_tasks_per_child
    assert conf["task_default_queue"] == "q1"
    visibility = conf["broker_transport_options"]["visibility_timeout"]
    assert visibility > conf["task_time_limit"]
    assert conf["task_time_limit"] > conf["task_soft_time_limit"]


def test_the_embedded_pool_uses_the_cpus_less_one_for_the_api(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.delenv("TRAJOPT_LOCAL_WORKERS", raising=False)
    cpus = len(os.sched_getaffinity(0))
    assert default_local_workers() == max(1, cpus - 1)
    assert Settings().local_workers == max(1, cpus - 1)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(8)))
    assert Settings().local_workers == 7
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0})
    assert Settings().local_workers == 1  # never zero
    monkeypatch.setenv("TRAJOPT_LOCAL_WORKERS", "3")
    assert Settings().local_workers == 3
