"""One error shape for every response: ``{"error": {"code", "message", "field", "issues"}}``.

Handlers turn the service's own :class:`ApiError`, request validation errors, unknown routes and
unexpected exceptions into that shape, so clients parse a single format.
"""

from __future__ import annotations

import logging
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

log = logging.getLogger(__name__)


class ApiError(Exception):
    """An error answered with ``status`` and the common body."""

    def __init__(
        self,
        status: int,
        code: str,
        message: str,
        *,
        field: str | None = None,
        issues: list[dict[str, Any]] | None = None,
        headers: dict[str, str] | None = None,
    ) -> None:
        super().__init__(message)
        self.status = status
        self.code = code
        self.message = message
        self.field = field
        self.issues = issues
        self.headers = headers


def error_body(
    code: str,
    message: str,
    field: str | None = None,
    issues: list[dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """The JSON body of an error."""
    body: dict[str, Any] = {"code": code, "message": message, "field": field}
    if issues is not None:
        body["issues"] = issues
    return {"error": body}


def not_found(kind: str, ident: str) -> ApiError:
    """404 for an unknown ``kind`` (job, scenario) named ``ident``."""
    return ApiError(404, f"{kind}_not_found", f"no {kind} {ident!r}")


def _dotted(loc: tuple[Any, ...] | list[Any]) -> str:
    parts = [str(p) for p in loc]
    if parts and parts[0] in ("body", "query", "path", "header"):
        parts = parts[1:]
    return ".".join(parts)


async def _api_error(_: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, ApiError)
    return JSONResponse(
        error_body(exc.code, exc.message, exc.field, exc.issues),
        status_code=exc.status,
        headers=exc.headers,
    )


async def _request_validation(_: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    issues = [
        {"field": _dotted(e.get("loc", ())), "message": str(e.get("msg")), "code": str(e["type"])}
        for e in exc.errors()
    ]
    first = issues[0] if issues else {"field": None, "message": "invalid request"}
    message = f"{len(issues)} invalid field(s): {first['field']}: {first['message']}"
    return JSONResponse(
        error_body("invalid_request", message, first["field"], issues), status_code=422
    )


async def _http_error(_: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, StarletteHTTPException)
    codes = {400: "malformed_body", 404: "not_found", 405: "method_not_allowed"}
    code = codes.get(exc.status_code, f"http_{exc.status_code}")
    return JSONResponse(
        error_body(code, str(exc.detail)),
        status_code=exc.status_code,
        headers=getattr(exc, "headers", None),
    )


async def _unexpected(request: Request, exc: Exception) -> JSONResponse:
    log.exception("unhandled error on %s %s", request.method, request.url.path, exc_info=exc)
    return JSONResponse(error_body("internal_error", "internal server error"), status_code=500)


def install_error_handlers(app: FastAPI) -> None:
    """Register the handlers that give every error the common shape."""
    app.add_exception_handler(ApiError, _api_error)
    app.add_exception_handler(RequestValidationError, _request_validation)
    app.add_exception_handler(StarletteHTTPException, _http_error)
    app.add_exception_handler(Exception, _unexpected)
