"""``/ui/``: the web pages (the caller's jobs, one job's page) and their script and style; ``/``
sends a browser to them.

The pages are static files of ``app.ui``; everything they show comes from the ``/v1`` API,
read by their script with the caller's key, so the pages themselves need no authentication.
Nothing is loaded from anywhere but this server (the Content-Security-Policy says so too).
"""

from __future__ import annotations

from functools import cache
from importlib.resources import files

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse, RedirectResponse, Response

router = APIRouter(prefix="/ui", include_in_schema=False)
root_router = APIRouter(include_in_schema=False)
"""``/``: a browser goes to the jobs page, an API client gets where things are."""

ROOT_LINKS = {
    "jobs_page": "/ui/",
    "docs": "/docs",
    "redoc": "/redoc",
    "openapi": "/openapi.json",
    "jobs": "/v1/jobs",
    "scenarios": "/v1/scenarios",
    "methods": "/v1/methods",
    "health": "/healthz",
    "ready": "/readyz",
}
"""What ``GET /`` lists for an API client (paths under the application's mount point)."""

CONTENT_SECURITY_POLICY = "; ".join(
    [
        "default-src 'none'",
        "script-src 'self'",
        "style-src 'self'",
        "img-src 'self' blob: data:",  # the plots arrive as blobs (fetched with the key)
        "connect-src 'self'",
        "base-uri 'none'",
        "form-action 'none'",
        "frame-ancestors 'none'",
    ]
)
"""The pages may load their own script, style and plots from this server, and nothing else."""

ASSETS = {"ui.js": "text/javascript", "ui.css": "text/css"}
"""The files under ``/ui/static/`` (and no other file of the package)."""


@cache
def _file(name: str) -> bytes:
    """A file of the ``app.ui`` package (read once)."""
    return (files("app.ui") / name).read_bytes()


def _page(name: str) -> Response:
    return Response(
        _file(name),
        media_type="text/html; charset=utf-8",
        headers={"Content-Security-Policy": CONTENT_SECURITY_POLICY, "Cache-Control": "no-cache"},
    )


@router.get("")
def ui_root() -> RedirectResponse:
    """``/ui`` -> ``/ui/`` (the pages' links are relative to it)."""
    return RedirectResponse("ui/", status_code=307)


@router.get("/")
def jobs_page() -> Response:
    """The caller's jobs, newest first, each linked to its page."""
    return _page("jobs.html")


@router.get("/jobs/{job_id}")
def job_page(job_id: str) -> Response:
    """One job: status, live progress while it runs, then its plots, verification and links."""
    return _page("job.html")


@router.get("/batches/{batch_id}")
def batch_page(batch_id: str) -> Response:
    """One batch: status and counts (refreshed while it runs), a row per child linked to its
    job's page, its plot and summary downloads."""
    return _page("batch.html")


@router.get("/static/{name}")
def asset(name: str) -> Response:
    """The pages' script and style sheet."""
    if name not in ASSETS:
        return Response(status_code=404)
    return Response(_file(name), media_type=ASSETS[name], headers={"Cache-Control": "no-cache"})


def _wants_html(request: Request) -> bool:
    """Whether the client asks for a page (a browser's Accept names text/html)."""
    return "text/html" in request.headers.get("accept", "").lower()


@root_router.get("/", response_model=None)
def root(request: Request) -> Response:
    """A browser (Accept: text/html) is sent to the jobs page (307 to ``/ui/``); any other
    client gets 200 JSON: the service's name and version and where its API, docs and pages
    are."""
    headers = {"Vary": "Accept"}
    if _wants_html(request):
        return RedirectResponse("ui/", status_code=307, headers=headers)
    prefix = str(request.scope.get("root_path", "")).rstrip("/")
    body = {
        "service": request.app.title,
        "version": request.app.version,
        "links": {name: f"{prefix}{path}" for name, path in ROOT_LINKS.items()},
    }
    return JSONResponse(body, headers=headers)
