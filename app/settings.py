"""Service settings from the environment: ``TRAJOPT_*``, ``DATABASE_URL`` and ``REDIS_URL``.

One object configures the API, the local dispatcher and the Celery worker, so every process of a
deployment reads the same limits and the same database.
"""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal
from urllib.parse import urlsplit

from pydantic import AliasChoices, Field, SecretStr, ValidationError, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict, SettingsError

AuthMode = Literal["single-user", "api-keys"]

MIN_SECRET_LENGTH = 32
"""Shortest accepted server secret (characters); 32 hex characters carry 128 bits."""

WEAK_SECRETS: frozenset[str] = frozenset(
    {
        "",
        "changeme",
        "change-me",
        "changethis",
        "secret",
        "password",
        "postgres",
        "trajopt",
        "admin",
    }
)
"""Values refused wherever a secret is required (placeholders and well-known defaults)."""

SECRET_FIELDS: frozenset[str] = frozenset({"api_key_secret", "database_url", "broker_url"})
"""Settings whose values no message shows (the secret, and URLs that may carry a password)."""

_SHOWN_VALUE_CHARS = 60


def secret_problem(secret: str) -> str | None:
    """Why ``secret`` is refused (never quoting it), or ``None`` when it is acceptable."""
    if not secret.strip():
        return "is not set"
    if secret.strip().lower() in WEAK_SECRETS:
        return "is a well-known default"
    if len(secret) < MIN_SECRET_LENGTH:
        return "is too short"
    return None


def default_data_dir() -> Path:
    """Where the embedded SQLite file lives: ``$XDG_DATA_HOME/trajopt`` (``~/.local/share``)."""
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "trajopt"


def default_local_workers() -> int:
    """Jobs the embedded pool runs at once by default: the usable CPUs less one for the API."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cpus = os.cpu_count() or 1
    return max(1, cpus - 1)


class Settings(BaseSettings):
    """All tunables of the service; defaults give the embedded mode (SQLite, no broker)."""

    model_config = SettingsConfigDict(env_prefix="TRAJOPT_", extra="ignore", populate_by_name=True)

    data_dir: Path = Field(default_factory=default_data_dir)
    database_url: str = Field(
        default="",
        validation_alias=AliasChoices("DATABASE_URL", "TRAJOPT_DATABASE_URL", "database_url"),
        description="SQLAlchemy URL; empty means a SQLite file in data_dir.",
    )
    broker_url: str = Field(
        default="",
        validation_alias=AliasChoices(
            "TRAJOPT_BROKER_URL", "REDIS_URL", "CELERY_BROKER_URL", "broker_url"
        ),
        description="Redis URL of the Celery broker; empty means jobs run in a local process pool.",
    )
    host: str = "127.0.0.1"
    port: int = Field(default=8000, ge=1, le=65535)
    auto_migrate: bool = True

    default_owner: str = "default"
    queue_name: str = "trajopt"
    local_workers: int = Field(
        default_factory=default_local_workers,
        ge=1,
        le=64,
        description="Processes of the embedded job pool (jobs run at once); default: the CPUs "
        "this process may use, less one for the API, at least one.",
    )

    max_attempts: int = Field(default=3, ge=1, le=20)
    default_time_limit_s: float = Field(default=300.0, gt=0)
    max_time_limit_s: float = Field(default=900.0, gt=0)
    soft_limit_margin_s: float = Field(default=60.0, ge=0)
    hard_limit_grace_s: float = Field(default=30.0, gt=0)
    visibility_timeout_s: float = Field(default=3600.0, gt=0)
    worker_max_tasks_per_child: int = Field(default=200, ge=1)
    worker_node_name: str = Field(
        default="trajopt-{pid}@%h",
        description="Celery node name; {pid} is the process id, %h the host name.",
    )

    max_streams: int = Field(
        default=200,
        ge=1,
        description="Event streams one API process keeps open at once, for all clients.",
    )
    max_streams_per_client: int = Field(
        default=10, ge=1, description="Event streams one client may keep open on one API process."
    )
    render_processes: int = Field(
        default=1,
        ge=1,
        le=16,
        description="Processes one API process renders plots in (started at the first plot).",
    )
    render_queue_per_client: int = Field(
        default=16,
        ge=1,
        description="Plots one client may have waiting or rendering on one API process (one "
        "renders at a time); past it, 429 too_many_renders.",
    )
    event_poll_interval_s: float = Field(default=0.05, gt=0, le=5)
    event_ping_interval_s: float = Field(default=15.0, gt=0)
    request_timeout_s: float = Field(default=2.0, gt=0)

    auth_mode: AuthMode = Field(
        default="single-user",
        description="single-user: every request acts as default_owner; api-keys: X-API-Key.",
    )
    api_key_secret: SecretStr = Field(
        default=SecretStr(""),
        description="Server secret keyed into the stored API-key hashes (HMAC-SHA-256); "
        "required in api-keys mode.",
    )
    cors_origins: str = Field(
        default="", description="Comma-separated browser origins allowed by CORS; empty: none."
    )
    max_body_bytes: int = Field(default=1_048_576, ge=1024)
    rate_rejected_per_window: int = Field(
        default=30,
        ge=0,
        description="Submissions refused with a 4xx (invalid, over a cap) a client may send per "
        "rate window; when used up, its submissions get 429 before validation. 0 disables (as "
        "does a submit limit of 0).",
    )
    rate_key_share: float = Field(
        default=1.0,
        gt=0,
        le=1,
        description="Share of each per-client rate limit one API key may use alone (1: all).",
    )
    rate_auth_failures_per_window: int = Field(
        default=30,
        ge=0,
        description="Failed authentications (401) one client address may cause per rate "
        "window (api-keys mode); past it the address gets 429 before any key lookup. "
        "0 disables.",
    )
    rate_window_s: float = Field(default=60.0, gt=0)
    rate_submit_per_window: int = Field(default=60, ge=0, description="0 disables the limit.")
    rate_read_per_window: int = Field(default=1200, ge=0, description="0 disables the limit.")
    max_active_jobs: int = Field(
        default=100, ge=1, description="Queued + running jobs one client may have."
    )
    max_batch_children: int = Field(
        default=100, ge=1, description="Children one batch may have (each an ordinary job)."
    )
    max_nodes: int = Field(
        default=1000, ge=3, description="Most nodes of a job (of each phase for a phased one)."
    )
    max_iterations: int = Field(
        default=2000,
        ge=1,
        description="Most iterations of a job; the default admits every method's own default "
        "and maximum (lgl-sqp: 600 by default, at most 2000).",
    )
    max_no_fly_zones: int = Field(default=20, ge=0)
    max_waypoints: int = Field(default=20, ge=0)

    lease_s: float = Field(
        default=30.0, gt=0, description="A running job whose heartbeat is older is re-queued."
    )
    sweep_interval_s: float = Field(default=5.0, gt=0)
    result_write_retry_s: float = Field(
        default=600.0,
        ge=0,
        description="How long a worker keeps a finished result while the database is "
        "unreachable, retrying its write.",
    )
    relay_interval_s: float = Field(
        default=1.0,
        gt=0,
        description="How often each API process sends the queued jobs that are due (outbox).",
    )
    requeue_queued_after_s: float = Field(
        default=900.0,
        ge=0,
        description="Re-send a job still queued after this long (lost message); 0 disables.",
    )

    @model_validator(mode="after")
    def _default_time_limit_within_cap(self) -> Settings:
        if self.default_time_limit_s > self.max_time_limit_s:
            self.default_time_limit_s = self.max_time_limit_s
        return self

    @model_validator(mode="after")
    def _refuse_default_secrets(self) -> Settings:
        if self.auth_mode != "api-keys":
            return self
        problem = secret_problem(self.api_key_secret.get_secret_value())
        if problem is not None:
            raise ValueError(
                f"TRAJOPT_API_KEY_SECRET {problem}; api-keys mode needs a random value of at "
                f"least {MIN_SECRET_LENGTH} characters (e.g. `openssl rand -hex 32`)"
            )
        password = urlsplit(self.database_url).password if "://" in self.database_url else None
        if password is not None and password.lower() in WEAK_SECRETS:
            raise ValueError("DATABASE_URL uses a default password; set a random one")
        return self

    @property
    def cors_origin_list(self) -> list[str]:
        """The configured CORS origins (empty: CORS closed)."""
        return [o.strip() for o in self.cors_origins.split(",") if o.strip()]

    @property
    def effective_database_url(self) -> str:
        """The configured database URL, or the embedded SQLite file under ``data_dir``."""
        if self.database_url:
            return normalize_database_url(self.database_url)
        return f"sqlite:///{(self.data_dir / 'trajopt.sqlite3').as_posix()}"

    @property
    def uses_broker(self) -> bool:
        """True when jobs go through Celery (a broker URL is set)."""
        return bool(self.broker_url)

    @property
    def max_hard_limit_s(self) -> float:
        """The longest hard time limit any job can get: the cap, both margins and the hold of
        a finished result while the database is away (see :mod:`worker.limits`)."""
        return (
            self.max_time_limit_s
            + self.soft_limit_margin_s
            + self.hard_limit_grace_s
            + self.result_write_retry_s
        )


def normalize_database_url(url: str) -> str:
    """Map ``postgres://``/``postgresql://`` to the psycopg 3 driver SQLAlchemy needs."""
    for prefix in ("postgres://", "postgresql://"):
        if url.startswith(prefix):
            return "postgresql+psycopg://" + url[len(prefix) :]
    return url


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The process-wide settings read once from the environment."""
    return Settings()


class ConfigurationError(Exception):
    """The environment's settings are invalid; ``problems`` holds one line per bad setting."""

    def __init__(self, problems: list[str]) -> None:
        super().__init__("; ".join(problems))
        self.problems = problems


def _env_set(name: str) -> bool:
    """Whether the environment sets ``name`` (names are matched case-insensitively)."""
    lowered = name.lower()
    return any(key.lower() == lowered for key in os.environ)


def env_name(field: str) -> str:
    """The environment variable that sets ``field`` (the one actually set, among aliases)."""
    info = Settings.model_fields.get(field)
    if info is None:  # already an alias, e.g. DATABASE_URL
        return field.upper()
    alias = info.validation_alias
    if isinstance(alias, AliasChoices):
        names = [c.upper() for c in alias.choices if isinstance(c, str) and c != field]
        given = [n for n in names if _env_set(n)]
        return (given or names)[0]
    return f"TRAJOPT_{field.upper()}"


def _shown(value: Any) -> str | None:
    """A given value as a message quotes it (cut when long); ``None`` for non-scalars."""
    if not isinstance(value, str | int | float) or isinstance(value, bool):
        return None
    text = str(value)
    if len(text) > _SHOWN_VALUE_CHARS:
        text = text[: _SHOWN_VALUE_CHARS - 3] + "..."
    return repr(text)


def settings_problems(exc: ValidationError) -> list[str]:
    """One line per invalid setting: its environment variable and the reason.

    The value given is shown only for settings outside ``SECRET_FIELDS``; ``str(exc)`` is never
    used, since pydantic's own text carries every input, secrets included.
    """
    problems: list[str] = []
    for error in exc.errors(include_url=False, include_context=False):
        message = str(error.get("msg", "invalid value")).removeprefix("Value error, ")
        loc = error.get("loc") or ()
        if not loc:  # model-level checks name their variables themselves
            line = message
        else:
            field = str(loc[0])
            line = f"{env_name(field)}: {message[:1].lower()}{message[1:]}"
            shown = None if field in SECRET_FIELDS else _shown(error.get("input"))
            if shown is not None:
                line += f" (got {shown})"
        if line not in problems:
            problems.append(line)
    return problems


def load_settings() -> Settings:
    """The process-wide settings; ``ConfigurationError`` (clean, secret-free) when invalid."""
    try:
        return get_settings()
    except ValidationError as exc:
        raise ConfigurationError(settings_problems(exc)) from None
    except SettingsError as exc:
        raise ConfigurationError([str(exc)]) from None
