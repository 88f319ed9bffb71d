"""``/ui/``: the web pages (the caller's jobs, one job's page) and their script and style.

The pages are static files of ``app.ui``; everything they show comes from the ``/v1`` API,
read by their script with the caller's key, so the pages themselves need no authentication.
Nothing is loaded from anywhere but this server (the Content-Security-Policy says so too).
"""

from __future__ import annotations

from functools import cache
from importlib.resources import files

from fastapi import APIRouter
from fastapi.responses import RedirectResponse, Response

router = APIRouter(prefix="/ui", include_in_schema=False)

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
