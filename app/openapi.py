"""The OpenAPI document: FastAPI's, plus the problem and result contracts as components.

Routes that take a problem read the raw JSON and validate it themselves (to report every error
at once), so their request body schema is set here: a problem document or a scenario request.
``/result`` answers the stored JSON text, so its schema (``ResultDocument``) is added here too.
Every error response gets the examples of the codes that operation can answer.
"""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi
from pydantic import BaseModel

from app.routes.examples import ERROR_EXAMPLES
from app.schemas import ProblemDocument
from app.schemas.batch import BatchRequest
from app.schemas.result import ResultDocument
from app.views import ScenarioJobRequest

PROBLEM_BODY_MARK = "x-problem-body"
PROBLEM_BODY_SCHEMA: dict[str, Any] = {
    "oneOf": [
        {"$ref": "#/components/schemas/ProblemDocument"},
        {"$ref": "#/components/schemas/ScenarioJobRequest"},
    ]
}
ERROR_REF = "#/components/schemas/ErrorResponse"

ERRORS_BY_STATUS: dict[int, list[str]] = {
    400: ["malformed_body"],
    401: ["missing_api_key", "invalid_api_key"],
    413: ["body_too_large"],
    415: ["unsupported_media_type"],
    422: ["invalid_parameter"],
    429: ["rate_limited"],
    503: ["database_unavailable"],
}
"""The error codes (keys of ``ERROR_EXAMPLES``) behind each status, unless an operation has its
own in :data:`OPERATION_ERRORS`; 404 depends on the path (:func:`_error_codes`)."""

OPERATION_ERRORS: dict[tuple[str, str], dict[int, list[str]]] = {
    ("post", "/v1/jobs"): {
        404: ["job_not_found"],
        422: [
            "invalid_problem",
            "invalid_request",
            "over_server_cap",
            "invalid_idempotency_key",
            "idempotency_key_reused",
        ],
        429: ["submit_rate_limited", "too_many_active_jobs"],
        503: ["queue_unavailable", "database_unavailable"],
    },
    ("post", "/v1/problems/validate"): {
        422: ["invalid_problem", "invalid_request", "over_server_cap"]
    },
    ("get", "/v1/jobs/{job_id}/result"): {409: ["job_not_finished", "result_unavailable"]},
    ("get", "/v1/jobs/{job_id}/trajectory.csv"): {
        409: ["job_not_finished", "result_unavailable", "no_trajectory"]
    },
    ("get", "/v1/jobs/{job_id}/plots"): {409: ["job_not_finished", "result_unavailable"]},
    ("get", "/v1/jobs/{job_id}/plots/{name}.{fmt}"): {
        404: ["job_not_found", "plot_not_found", "plot_format_not_found"],
        409: ["job_not_finished", "result_unavailable"],
        429: ["rate_limited", "too_many_renders"],
        503: ["database_unavailable", "render_unavailable"],
    },
    ("delete", "/v1/jobs/{job_id}"): {409: ["job_finished"]},
    ("get", "/v1/jobs/{job_id}/events"): {429: ["rate_limited", "too_many_streams"]},
    ("get", "/readyz"): {503: ["not_ready"]},
    ("post", "/v1/batches"): {
        422: [
            "invalid_batch",
            "over_server_cap",
            "invalid_idempotency_key",
            "idempotency_key_reused",
        ],
        429: ["submit_rate_limited", "too_many_active_jobs"],
    },
    ("get", "/v1/batches/{batch_id}/plot.{fmt}"): {
        404: ["batch_not_found", "plot_format_not_found"],
        429: ["rate_limited", "too_many_renders"],
        503: ["database_unavailable", "render_unavailable"],
    },
}

BODY_ERRORS: dict[str, dict[str, Any]] = {
    "400": {"description": "The body is not decodable JSON (or is empty)."},
    "415": {"description": "The body is not sent as Content-Type: application/json."},
}
"""Responses of every operation that takes a JSON body (and only of those)."""


def _add_model(components: dict[str, Any], model: type[BaseModel]) -> None:
    schema = model.model_json_schema(ref_template="#/components/schemas/{model}")
    definitions = schema.pop("$defs", {})
    for name, definition in {**definitions, model.__name__: schema}.items():
        if name in components:  # FastAPI's own rendering of a response model: keep it
            if _without_defaults(components[name]) != _without_defaults(definition):
                raise RuntimeError(f"OpenAPI component {name!r} is defined twice, differently")
            continue
        components[name] = definition


def _without_defaults(schema: Any) -> Any:
    """``schema`` without its ``default`` members (FastAPI leaves out ``"default": null``)."""
    if isinstance(schema, dict):
        return {k: _without_defaults(v) for k, v in schema.items() if k != "default"}
    if isinstance(schema, list):
        return [_without_defaults(v) for v in schema]
    return schema


def build_openapi(app: FastAPI) -> dict[str, Any]:
    """Generate the OpenAPI document of ``app`` with the problem bodies filled in."""
    schema = get_openapi(
        title=app.title,
        version=app.version,
        description=app.description,
        routes=app.routes,
    )
    components = schema.setdefault("components", {}).setdefault("schemas", {})
    for model in (ProblemDocument, ScenarioJobRequest, ResultDocument, BatchRequest):
        _add_model(components, model)
    for path, operations in schema.get("paths", {}).items():
        for method, operation in operations.items():
            if not isinstance(operation, dict):
                continue
            _use_error_shape_for_422(operation)
            if operation.pop(PROBLEM_BODY_MARK, False):
                content = operation["requestBody"]["content"]["application/json"]
                content["schema"] = PROBLEM_BODY_SCHEMA
            _body_errors(operation)
            _error_examples(method, path, operation)
    for name in ("HTTPValidationError", "ValidationError"):
        components.pop(name, None)
    return schema


def _error_codes(method: str, path: str, status: int) -> list[str]:
    """The error codes operation ``method path`` can answer with ``status``."""
    own = OPERATION_ERRORS.get((method, path), {})
    if status in own:
        return own[status]
    if status == 404:
        if "{job_id}" in path:
            return ["job_not_found"]
        if "{batch_id}" in path:
            return ["batch_not_found"]
        if "{name}" in path:
            return ["scenario_not_found"]
    return ERRORS_BY_STATUS.get(status, [])


def _body_errors(operation: dict[str, Any]) -> None:
    """400 and 415 belong to the operations that read a body, and to no other."""
    responses = operation.setdefault("responses", {})
    if "requestBody" not in operation:
        responses.pop("400", None)
        return
    for status, response in BODY_ERRORS.items():
        entry = responses.setdefault(status, {})
        entry["description"] = response["description"]
        entry["content"] = {"application/json": {"schema": {"$ref": ERROR_REF}}}


def _error_examples(method: str, path: str, operation: dict[str, Any]) -> None:
    """Give each error response of the operation the examples of the codes it can answer."""
    for status, response in operation.get("responses", {}).items():
        content = response.get("content", {}).get("application/json", {})
        if content.get("schema", {}).get("$ref") != ERROR_REF:
            continue
        codes = _error_codes(method, path, int(status))
        if not codes:
            raise RuntimeError(f"{method.upper()} {path} {status}: no error example")
        content["examples"] = {
            code: {k: v for k, v in ERROR_EXAMPLES[code].items() if k != "x-status"}
            for code in codes
        }


def _use_error_shape_for_422(operation: dict[str, Any]) -> None:
    """FastAPI documents its own 422 body; this service answers with ``ErrorResponse``."""
    response = operation.get("responses", {}).get("422")
    if response is None:
        return
    schema = response.get("content", {}).get("application/json", {}).get("schema", {})
    if schema.get("$ref", "").endswith("/HTTPValidationError"):
        schema["$ref"] = "#/components/schemas/ErrorResponse"
        response["description"] = "Invalid request: every invalid field, listed."


def install_openapi(app: FastAPI) -> None:
    """Make ``app.openapi()`` return (and cache) :func:`build_openapi`'s document."""

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            app.openapi_schema = build_openapi(app)
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]
