"""``/healthz``, ``/readyz`` and ``/metrics``."""

from __future__ import annotations

from fastapi import APIRouter, Response
from fastapi.responses import JSONResponse
from prometheus_client import CONTENT_TYPE_LATEST, generate_latest
from sqlalchemy import text

from app.deps import ServiceDep
from app.errors import error_body
from app.views import ErrorResponse, Health

router = APIRouter(tags=["operations"])


@router.get("/healthz", response_model=Health, summary="Process is up")
def healthz() -> Health:
    """Always 200 while the process serves requests."""
    return Health(status="ok")


@router.get(
    "/readyz",
    response_model=Health,
    responses={503: {"model": ErrorResponse, "description": "A dependency is unreachable."}},
    summary="Database and queue reachable",
)
def readyz(service: ServiceDep) -> Health | JSONResponse:
    """200 when the database answers and the broker (or local pool) accepts work, else 503."""
    checks: dict[str, str] = {}
    try:
        with service.database.reader() as session:
            session.execute(text("SELECT 1"))
        checks["database"] = "ok"
    except Exception as exc:
        checks["database"] = f"unreachable: {type(exc).__name__}"
    problem = service.dispatcher.ping()
    checks[service.dispatcher.kind] = problem or "ok"
    failing = {k: v for k, v in checks.items() if v != "ok"}
    if failing:
        message = "; ".join(f"{k}: {v}" for k, v in failing.items())
        body = {**error_body("not_ready", message), "checks": checks}
        return JSONResponse(body, status_code=503)
    return Health(status="ready", checks=checks)


@router.get(
    "/metrics",
    response_class=Response,
    responses={200: {"content": {"text/plain": {}}}},
    summary="Prometheus metrics",
)
def metrics(service: ServiceDep) -> Response:
    """Jobs by status, queue depth and the solve-time histogram, in Prometheus text format."""
    return Response(generate_latest(service.registry), media_type=CONTENT_TYPE_LATEST)
