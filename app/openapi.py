"""The OpenAPI document: FastAPI's, plus the problem contract's JSON Schema as components.

Routes that take a problem read the raw JSON and validate it themselves (to report every error
at once), so their request body schema is set here: a problem document or a scenario request.
"""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi
from pydantic import BaseModel

from app.schemas import ProblemDocument
from app.views import ScenarioJobRequest

PROBLEM_BODY_MARK = "x-problem-body"
PROBLEM_BODY_SCHEMA: dict[str, Any] = {
    "oneOf": [
        {"$ref": "#/components/schemas/ProblemDocument"},
        {"$ref": "#/components/schemas/ScenarioJobRequest"},
    ]
}


def _add_model(components: dict[str, Any], model: type[BaseModel]) -> None:
    schema = model.model_json_schema(ref_template="#/components/schemas/{model}")
    definitions = schema.pop("$defs", {})
    for name, definition in {**definitions, model.__name__: schema}.items():
        if name in components and components[name] != definition:
            raise RuntimeError(f"OpenAPI component {name!r} is defined twice, differently")
        components[name] = definition


def build_openapi(app: FastAPI) -> dict[str, Any]:
    """Generate the OpenAPI document of ``app`` with the problem bodies filled in."""
    schema = get_openapi(
        title=app.title,
        version=app.version,
        description=app.description,
        routes=app.routes,
    )
    components = schema.setdefault("components", {}).setdefault("schemas", {})
    for model in (ProblemDocument, ScenarioJobRequest):
        _add_model(components, model)
    for operations in schema.get("paths", {}).values():
        for operation in operations.values():
            if not isinstance(operation, dict):
                continue
            _use_error_shape_for_422(operation)
            if operation.pop(PROBLEM_BODY_MARK, False):
                content = operation["requestBody"]["content"]["application/json"]
                content["schema"] = PROBLEM_BODY_SCHEMA
    for name in ("HTTPValidationError", "ValidationError"):
        components.pop(name, None)
    return schema


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
