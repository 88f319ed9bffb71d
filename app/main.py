"""The FastAPI application: routes, error handlers, OpenAPI, and start-up/shutdown of services."""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from importlib import metadata
from typing import Any

from fastapi import Depends, FastAPI
from fastapi.middleware.cors import CORSMiddleware

from app.auth import API_KEY_HEADER
from app.deps import get_owner, get_principal
from app.dispatch import Dispatcher, make_dispatcher
from app.dispatch.local import LocalDispatcher
from app.docs_ui import install_docs
from app.errors import install_error_handlers
from app.events import PollingWaker, RedisWaker, Waker
from app.metrics import build_registry
from app.middleware import BodySizeLimit
from app.openapi import install_openapi
from app.ratelimit import MemoryRateLimiter, RateLimiter, RedisRateLimiter
from app.render_pool import RenderPool
from app.routes import batches, catalog, events, health, jobs, problems, report, ui
from app.settings import Settings, get_settings
from app.state import ServiceState
from app.storage.migrate import upgrade_database
from app.storage.session import get_database
from app.stream_hub import StreamHub
from app.sweeper import Sweeper
from app.views import ErrorResponse

log = logging.getLogger(__name__)

DESCRIPTION = """\
Hypersonic entry trajectory optimization by sequential convex programming, as a job service.

Submit a problem document (or a built-in scenario with overrides) to `POST /v1/jobs`, then poll
`GET /v1/jobs/{id}`, stream `GET /v1/jobs/{id}/events`, and fetch `GET /v1/jobs/{id}/result`.
Every error has the body `{"error": {"code", "message", "field", "issues"}}`.
"""


def _version() -> str:
    try:
        return metadata.version("entry-trajopt")
    except metadata.PackageNotFoundError:
        return "0.0.0"


def build_service(settings: Settings, dispatcher: Dispatcher | None = None) -> ServiceState:
    """Open the database (migrating it if enabled), start the dispatcher, set up metrics."""
    database = get_database(settings.effective_database_url)
    if settings.auto_migrate:
        upgrade_database(database.engine)
    dispatcher = dispatcher or make_dispatcher(settings)
    dispatcher.start()
    waker: Waker
    if settings.uses_broker:
        waker = RedisWaker(settings.broker_url, settings.event_poll_interval_s * 10)
    else:
        waker = PollingWaker(settings.event_poll_interval_s)
        if isinstance(dispatcher, LocalDispatcher):
            dispatcher.on_done = waker.notify
    rate_limiter: RateLimiter
    if settings.uses_broker:
        rate_limiter = RedisRateLimiter(
            settings.broker_url, settings.queue_name, settings.request_timeout_s
        )
    else:
        rate_limiter = MemoryRateLimiter()
    renders = RenderPool(settings.render_processes, settings.render_queue_per_client)
    return ServiceState(
        settings=settings,
        database=database,
        dispatcher=dispatcher,
        waker=waker,
        registry=build_registry(database, dispatcher, renders),
        rate_limiter=rate_limiter,
        streams=StreamHub(
            database,
            waker,
            max_streams=settings.max_streams,
            max_streams_per_client=settings.max_streams_per_client,
            min_read_gap_s=settings.event_poll_interval_s,
        ),
        renders=renders,
    )


def auth_banner(settings: Settings) -> str:
    """The one-line description of the authentication mode printed at start-up."""
    if settings.auth_mode == "api-keys":
        return f"auth: api-keys (every /v1 request needs an {API_KEY_HEADER} header)"
    return (
        f"auth: single-user (no API keys; every request acts as {settings.default_owner!r}); "
        "set TRAJOPT_AUTH_MODE=api-keys before exposing the service"
    )


def _end_notice(settings: Settings, service: ServiceState) -> Any:
    if settings.uses_broker:
        from worker.notify import RedisNotifier

        notifier = RedisNotifier(settings.broker_url)
        return lambda job_id: notifier(job_id, "end")
    waker = service.waker
    return waker.notify if isinstance(waker, PollingWaker) else None


_V1_RESPONSES: dict[int | str, dict[str, Any]] = {
    400: {"model": ErrorResponse, "description": "The body is not decodable JSON."},
    401: {"model": ErrorResponse, "description": "Missing, unknown or revoked API key."},
    413: {"model": ErrorResponse, "description": "The body is over the size limit."},
    429: {"model": ErrorResponse, "description": "Rate limit; retry after Retry-After."},
    503: {"model": ErrorResponse, "description": "The database is unreachable; retry later."},
}


def create_app(settings: Settings | None = None, dispatcher: Dispatcher | None = None) -> FastAPI:
    """A new application; services start in its lifespan.

    ``settings`` default to the environment; ``dispatcher`` to Celery or the local pool.
    """
    settings = settings or get_settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        service = build_service(settings, dispatcher)
        app.state.service = service
        sweeper = Sweeper(
            service.database, service.dispatcher, settings, _end_notice(settings, service)
        )
        sweeper.start()
        log.info(
            "trajopt API ready: jobs run %s; database %s; %s",
            "on Celery workers" if settings.uses_broker else "in a local process pool",
            service.database.engine.url.render_as_string(hide_password=True),
            auth_banner(settings),
        )
        try:
            yield
        finally:
            sweeper.stop()
            service.renders.shutdown()
            service.dispatcher.shutdown()
            service.rate_limiter.close()
            await service.streams.close()
            await service.waker.close()

    app = FastAPI(
        title="trajopt",
        version=_version(),
        description=DESCRIPTION,
        lifespan=lifespan,
        docs_url=None,  # served by install_docs, from local files
        redoc_url=None,
    )
    install_docs(app)
    install_error_handlers(app)
    guarded = (jobs, report, batches, events)
    for module, guard in ((m, get_principal) for m in guarded):
        app.include_router(module.router, dependencies=[Depends(guard)], responses=_V1_RESPONSES)
    for module in (catalog, problems):  # no owner of their own: count them as reads here
        app.include_router(
            module.router, dependencies=[Depends(get_owner)], responses=_V1_RESPONSES
        )
    app.include_router(health.router)
    app.include_router(ui.router)
    app.include_router(ui.root_router)
    install_openapi(app)
    if settings.cors_origin_list:
        app.add_middleware(
            CORSMiddleware,
            allow_origins=settings.cors_origin_list,
            allow_methods=["GET", "POST", "DELETE"],
            allow_headers=[API_KEY_HEADER, "Content-Type", "Idempotency-Key", "Last-Event-ID"],
            expose_headers=["Location", "Retry-After", "Idempotent-Replayed"],
        )
    app.add_middleware(BodySizeLimit, max_bytes=settings.max_body_bytes)
    return app
