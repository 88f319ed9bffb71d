"""The FastAPI application: routes, error handlers, OpenAPI, and start-up/shutdown of services."""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from importlib import metadata

from fastapi import FastAPI

from app.dispatch import Dispatcher, make_dispatcher
from app.dispatch.local import LocalDispatcher
from app.errors import install_error_handlers
from app.events import PollingWaker, RedisWaker, Waker
from app.metrics import build_registry
from app.openapi import install_openapi
from app.routes import catalog, events, health, jobs, problems
from app.settings import Settings, get_settings
from app.state import ServiceState
from app.storage.migrate import upgrade_database
from app.storage.session import get_database

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
    return ServiceState(
        settings=settings,
        database=database,
        dispatcher=dispatcher,
        waker=waker,
        registry=build_registry(database, dispatcher),
    )


def create_app(settings: Settings | None = None, dispatcher: Dispatcher | None = None) -> FastAPI:
    """A new application; services start in its lifespan.

    ``settings`` default to the environment; ``dispatcher`` to Celery or the local pool.
    """
    settings = settings or get_settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        service = build_service(settings, dispatcher)
        app.state.service = service
        log.info(
            "trajopt API ready: jobs run %s; database %s",
            "on Celery workers" if settings.uses_broker else "in a local process pool",
            service.database.engine.url.render_as_string(hide_password=True),
        )
        try:
            yield
        finally:
            service.dispatcher.shutdown()
            await service.waker.close()

    app = FastAPI(
        title="trajopt",
        version=_version(),
        description=DESCRIPTION,
        lifespan=lifespan,
    )
    install_error_handlers(app)
    for module in (jobs, events, catalog, problems, health):
        app.include_router(module.router)
    install_openapi(app)
    return app
