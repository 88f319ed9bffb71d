"""Validate JSON against the schemas of an OpenAPI 3.1 document, its ``$ref`` s resolved."""

from __future__ import annotations

from typing import Any

import jsonschema
from referencing import Registry, Resource
from referencing.jsonschema import DRAFT202012

SPEC_URI = "urn:trajopt:openapi"


class OpenApiSchemas:
    """The schemas of one OpenAPI document (JSON Schema 2020-12, as OpenAPI 3.1 has them)."""

    def __init__(self, spec: dict[str, Any]) -> None:
        self.spec = spec
        resource = Resource.from_contents(spec, default_specification=DRAFT202012)
        self.registry: Registry[Any] = Registry().with_resource(SPEC_URI, resource)

    def errors(self, instance: Any, schema: dict[str, Any]) -> list[str]:
        """Every way ``instance`` breaks ``schema`` (a schema of the document, refs and all)."""
        validator = jsonschema.Draft202012Validator(_absolute(schema), registry=self.registry)
        return [
            f"{'/'.join(str(p) for p in e.absolute_path) or '(root)'}: {e.message[:300]}"
            for e in validator.iter_errors(instance)
        ]

    def component(self, name: str) -> dict[str, Any]:
        """A reference to ``#/components/schemas/name``."""
        assert name in self.spec["components"]["schemas"], name
        return {"$ref": f"#/components/schemas/{name}"}

    def response_schema(self, path: str, method: str, status: int) -> dict[str, Any]:
        """The JSON schema the document gives the response ``status`` of ``method path``."""
        response = self.spec["paths"][path][method]["responses"][str(status)]
        schema: dict[str, Any] = response["content"]["application/json"]["schema"]
        return schema


def _absolute(schema: Any) -> Any:
    """``schema`` with its document-relative ``$ref`` s pointing into the registered document."""
    if isinstance(schema, dict):
        return {
            k: SPEC_URI + v
            if k == "$ref" and isinstance(v, str) and v.startswith("#")
            else _absolute(v)
            for k, v in schema.items()
        }
    if isinstance(schema, list):
        return [_absolute(v) for v in schema]
    return schema
