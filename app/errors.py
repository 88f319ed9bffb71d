"""One error shape for every response: ``{"error": {"code", "message", "field", "issues"}}``.

Handlers turn the service's own :class:`ApiError`, request validation errors, unknown routes,
an unreachable database and unexpected exceptions into that shape, so clients parse a single
format. A list of issues is cut to its first :data:`MAX_ISSUES`; ``issues_total`` counts them all.
"""

from __future__ import annotations

import json
import logging
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from sqlalchemy.exc import DBAPIError
from sqlalchemy.exc import TimeoutError as PoolTimeoutError
from starlette.exceptions import HTTPException as StarletteHTTPException

from app.storage.session import database_unreachable

log = logging.getLogger(__name__)

MAX_ISSUES = 50
"""Most issues one error response lists (the first ones); ``issues_total`` counts them all."""
DATABASE_RETRY_AFTER_S = 5
"""Retry-After of a request refused because the database is unreachable."""


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
        issues_total: int | None = None,
    ) -> None:
        super().__init__(message)
        self.status = status
        self.code = code
        self.message = message
        self.field = field
        self.issues = issues[:MAX_ISSUES] if issues is not None else None
        self.issues_total = issues_total if issues_total is not None else len(issues or ())
        self.headers = headers


def issues_message(what: str, total: int, first_field: str | None, first_message: str) -> str:
    """The message of a 422 listing issues: how many, the first, and whether the list is cut."""
    message = f"{what} {total} error(s); first: {first_field or '(document)'}: {first_message}"
    if total > MAX_ISSUES:
        message += f" (issues lists the first {MAX_ISSUES})"
    return message


def error_body(
    code: str,
    message: str,
    field: str | None = None,
    issues: list[dict[str, Any]] | None = None,
    issues_total: int | None = None,
) -> dict[str, Any]:
    """The JSON body of an error; ``issues`` is cut to the first :data:`MAX_ISSUES`."""
    body: dict[str, Any] = {"code": code, "message": message, "field": field}
    if issues is not None:
        body["issues"] = issues[:MAX_ISSUES]
        body["issues_total"] = issues_total if issues_total is not None else len(issues)
    return {"error": body}


def not_found(kind: str, ident: str) -> ApiError:
    """404 for an unknown ``kind`` (job, scenario) named ``ident``."""
    return ApiError(404, f"{kind}_not_found", f"no {kind} {ident!r}")


def malformed_json(error: json.JSONDecodeError) -> ApiError:
    """400 ``malformed_body`` for a body that is not JSON, naming where decoding stopped."""
    return ApiError(
        400,
        "malformed_body",
        f"the body is not valid JSON: {error.msg} at line {error.lineno}, column {error.colno} "
        f"(character {error.pos})",
    )


def malformed_text(error: UnicodeDecodeError) -> ApiError:
    """400 ``malformed_body`` for a body that is not UTF-8 text, naming the first bad byte."""
    return ApiError(
        400,
        "malformed_body",
        f"the body is not valid JSON: it is not UTF-8 text ({error.reason} at byte {error.start})",
    )


def undecodable_body(body: bytes | str | None) -> ApiError:
    """The ``malformed_body`` error of a request body that ``json.loads`` refused."""
    if isinstance(body, bytes):
        try:
            body = body.decode("utf-8")  # JSON is UTF-8 (RFC 8259)
        except UnicodeDecodeError as exc:
            return malformed_text(exc)
    try:
        json.loads(body or "")
    except json.JSONDecodeError as exc:
        return malformed_json(exc)
    except UnicodeDecodeError as exc:  # json.loads detects UTF-16 and UTF-32 on its own
        return malformed_text(exc)
    return ApiError(400, "malformed_body", "the body is not valid JSON")


def _body_error(request: Request, exc: RequestValidationError) -> ApiError | None:
    """FastAPI's errors of a body that is absent, not JSON, or not labelled JSON, or None."""
    errors = exc.errors()
    for error in errors:
        if error.get("type") == "json_invalid":
            loc = tuple(error.get("loc", ()))
            pos = loc[1] if len(loc) > 1 and isinstance(loc[1], int) else 0
            doc = exc.body if isinstance(exc.body, str) else ""
            message = str((error.get("ctx") or {}).get("error", "invalid JSON"))
            return malformed_json(json.JSONDecodeError(message, doc, pos))
    if len(errors) != 1 or tuple(errors[0].get("loc", ())) != ("body",):
        return None
    if errors[0].get("type") == "missing":  # no body at all
        return malformed_json(json.JSONDecodeError("Expecting value", "", 0))
    if isinstance(errors[0].get("input"), bytes):  # FastAPI reads JSON only if it is labelled so
        given = request.headers.get("content-type")
        sent = f"Content-Type: {given}" if given else "no Content-Type"
        return ApiError(
            415,
            "unsupported_media_type",
            f"the body must be JSON sent with Content-Type: application/json; got {sent}",
            field="Content-Type",
        )
    return None


def _dotted(loc: tuple[Any, ...] | list[Any]) -> str:
    parts = [str(p) for p in loc]
    if parts and parts[0] in ("body", "query", "path", "header"):
        parts = parts[1:]
    return ".".join(parts)


async def _api_error(_: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, ApiError)
    return JSONResponse(
        error_body(exc.code, exc.message, exc.field, exc.issues, exc.issues_total),
        status_code=exc.status,
        headers=exc.headers,
    )


async def _request_validation(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    malformed = _body_error(request, exc)
    if malformed is not None:
        return await _api_error(request, malformed)
    errors = exc.errors()
    issues = [
        {"field": _dotted(e.get("loc", ())), "message": str(e.get("msg")), "code": str(e["type"])}
        for e in errors[:MAX_ISSUES]
    ]
    first = issues[0] if issues else {"field": None, "message": "invalid request"}
    message = f"{len(errors)} invalid field(s): {first['field']}: {first['message']}"
    if len(errors) > MAX_ISSUES:
        message += f" (issues lists the first {MAX_ISSUES})"
    return JSONResponse(
        error_body("invalid_request", message, first["field"], issues, len(errors)),
        status_code=422,
    )


async def _http_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, StarletteHTTPException)
    cause = exc.__cause__
    if exc.status_code == 400 and isinstance(cause, UnicodeDecodeError):  # FastAPI's json.loads
        return await _api_error(request, undecodable_body(cause.object))
    codes = {400: "malformed_body", 404: "not_found", 405: "method_not_allowed"}
    code = codes.get(exc.status_code, f"http_{exc.status_code}")
    return JSONResponse(
        error_body(code, str(exc.detail)),
        status_code=exc.status_code,
        headers=getattr(exc, "headers", None),
    )


async def _database_error(request: Request, exc: Exception) -> JSONResponse:
    if not database_unreachable(exc):
        return await _unexpected(request, exc)
    log.warning(
        "database unavailable on %s %s: %s",
        request.method,
        request.url.path,
        str(getattr(exc, "orig", None) or exc).strip().splitlines()[0],
    )
    return JSONResponse(
        error_body(
            "database_unavailable",
            f"the database is unreachable; retry after {DATABASE_RETRY_AFTER_S} s",
        ),
        status_code=503,
        headers={"Retry-After": str(DATABASE_RETRY_AFTER_S)},
    )


async def _unexpected(request: Request, exc: Exception) -> JSONResponse:
    log.exception("unhandled error on %s %s", request.method, request.url.path, exc_info=exc)
    return JSONResponse(error_body("internal_error", "internal server error"), status_code=500)


def install_error_handlers(app: FastAPI) -> None:
    """Register the handlers that give every error the common shape."""
    app.add_exception_handler(ApiError, _api_error)
    app.add_exception_handler(RequestValidationError, _request_validation)
    app.add_exception_handler(StarletteHTTPException, _http_error)
    for database_error in (DBAPIError, PoolTimeoutError):  # handled here: the connection stays
        app.add_exception_handler(database_error, _database_error)
    app.add_exception_handler(Exception, _unexpected)
