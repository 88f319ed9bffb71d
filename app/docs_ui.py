"""The interactive API docs (``/docs`` Swagger UI, ``/redoc`` ReDoc), served without a network.

FastAPI's own pages load their JavaScript, CSS, favicon and (ReDoc) Google fonts from CDNs, so
on a machine without internet they stay blank. Here the same pages reference only files served
by this application: the Swagger UI and ReDoc bundles shipped in the ``fastapi-offline`` package,
mounted at :data:`STATIC_URL`. The pages read the application's own ``/openapi.json``. The ReDoc
bundle names one more asset, its sidebar's "API docs by Redocly" logo on a CDN: it is served
with that address replaced by an inline image, so the page asks no other host for anything.
"""

from __future__ import annotations

from functools import cache
from importlib.resources import files
from pathlib import Path
from typing import Any

from fastapi import FastAPI, Request
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
from fastapi.responses import HTMLResponse, Response
from fastapi.staticfiles import StaticFiles

DOCS_URL = "/docs"
REDOC_URL = "/redoc"
STATIC_URL = "/docs-static"
"""Where the bundled Swagger UI and ReDoc files are served."""

CONTENT_SECURITY_POLICY = "; ".join(
    [
        "default-src 'self'",
        "script-src 'self' 'unsafe-inline' 'unsafe-eval'",  # start-up script; ReDoc's ajv
        "style-src 'self' 'unsafe-inline'",  # styles the bundles inject
        "img-src 'self' data:",  # ReDoc's sidebar logo: inline (redoc_bundle)
        "font-src 'self' data:",
        "worker-src 'self' blob:",  # ReDoc's search index
        "connect-src 'self'",
    ]
)
"""The docs pages may load nothing from anywhere but this server."""

SWAGGER_UI_PARAMETERS: dict[str, Any] = {
    "validatorUrl": None,  # no badge that sends the document to an online validator
}


REDOC_BUNDLE = "redoc.standalone.js"
REDOC_CDN_LOGO = "https://cdn.redoc.ly/redoc/logo-mini.svg"
"""The one address of another host in the ReDoc bundle: its sidebar's logo."""
INLINE_LOGO = (
    "data:image/svg+xml,%3Csvg xmlns='http://www.w3.org/2000/svg' width='16' height='16'%3E"
    "%3Crect x='3' y='3' width='10' height='10' rx='2' fill='%23888'/%3E%3C/svg%3E"
)
"""A small grey square drawn in place of the logo (an inline image: no request at all)."""


def static_directory() -> Path:
    """The folder of the ``fastapi-offline`` package that holds the Swagger UI and ReDoc files."""
    return Path(str(files("fastapi_offline") / "static"))


@cache
def redoc_bundle() -> bytes:
    """The ReDoc bundle with its CDN logo replaced by :data:`INLINE_LOGO` (read once)."""
    text = (static_directory() / REDOC_BUNDLE).read_text(encoding="utf-8")
    return text.replace(REDOC_CDN_LOGO, INLINE_LOGO).encode("utf-8")


def _prefix(request: Request) -> str:
    """The mount point of the application behind a proxy (``root_path``), or ``""``."""
    return str(request.scope.get("root_path", "")).rstrip("/")


def swagger_ui_page(app: FastAPI, request: Request) -> HTMLResponse:
    """The Swagger UI page of ``app``, every asset from :data:`STATIC_URL`."""
    root = _prefix(request)
    page = get_swagger_ui_html(
        openapi_url=f"{root}{app.openapi_url}",
        title=f"{app.title} - Swagger UI",
        swagger_js_url=f"{root}{STATIC_URL}/swagger-ui-bundle.js",
        swagger_css_url=f"{root}{STATIC_URL}/swagger-ui.css",
        swagger_favicon_url=f"{root}{STATIC_URL}/favicon.png",
        swagger_ui_parameters=SWAGGER_UI_PARAMETERS,
    )
    return _same_origin_only(page)


def redoc_page(app: FastAPI, request: Request) -> HTMLResponse:
    """The ReDoc page of ``app``, every asset from :data:`STATIC_URL` and no web fonts."""
    root = _prefix(request)
    page = get_redoc_html(
        openapi_url=f"{root}{app.openapi_url}",
        title=f"{app.title} - ReDoc",
        redoc_js_url=f"{root}{STATIC_URL}/{REDOC_BUNDLE}",
        redoc_favicon_url=f"{root}{STATIC_URL}/favicon.png",
        with_google_fonts=False,
    )
    return _same_origin_only(page)


def _same_origin_only(page: HTMLResponse) -> HTMLResponse:
    """``page`` with :data:`CONTENT_SECURITY_POLICY`: nothing is fetched from elsewhere."""
    page.headers["Content-Security-Policy"] = CONTENT_SECURITY_POLICY
    return page


def install_docs(app: FastAPI) -> None:
    """Serve ``/docs``, ``/redoc`` and their assets; create ``app`` with ``docs_url=None``."""
    if app.docs_url is not None or app.redoc_url is not None:
        raise RuntimeError("create the application with docs_url=None and redoc_url=None")

    @app.get(f"{STATIC_URL}/{REDOC_BUNDLE}", include_in_schema=False)
    async def redoc_script() -> Response:
        """The ReDoc bundle, its logo inline (before the mount, which would serve the file)."""
        return Response(redoc_bundle(), media_type="text/javascript; charset=utf-8")

    app.mount(STATIC_URL, StaticFiles(directory=static_directory()), name="docs-static")

    @app.get(DOCS_URL, include_in_schema=False)
    async def swagger_ui(request: Request) -> HTMLResponse:
        """Swagger UI."""
        return swagger_ui_page(app, request)

    @app.get(REDOC_URL, include_in_schema=False)
    async def redoc(request: Request) -> HTMLResponse:
        """ReDoc."""
        return redoc_page(app, request)
