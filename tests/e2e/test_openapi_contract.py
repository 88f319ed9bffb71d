"""A real server's answers match its own OpenAPI document.

A job runs through a real ``trajopt serve`` (embedded defaults); its ``/result`` and
``/history`` bodies are validated with ``jsonschema`` against the schemas that the same
server's ``/openapi.json`` documents, ``$ref`` s resolved. Bodies that are not JSON get the
documented 400 over real HTTP.
"""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from tests.integration.harness import SCENARIO, ApiServer, ServiceClient
from tests.openapi_schemas import OpenApiSchemas

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def spec(embedded_server: ApiServer) -> dict[str, Any]:
    document: dict[str, Any] = httpx.get(f"{embedded_server.base_url}/openapi.json").json()
    return document


def _documented(
    schemas: OpenApiSchemas, path: str, method: str, response: httpx.Response
) -> list[str]:
    schema = schemas.response_schema(path, method, response.status_code)
    return schemas.errors(response.json(), schema)


def test_result_and_history_of_a_real_job_match_the_document(
    embedded_client: ServiceClient, spec: dict[str, Any]
) -> None:
    schemas = OpenApiSchemas(spec)
    job = embedded_client.submit({"scenario": SCENARIO, "method": {"nodes": 40}})
    early = embedded_client.http.get(f"/v1/jobs/{job['id']}/result")
    if early.status_code == 409:  # not finished yet: the documented 409
        assert _documented(schemas, "/v1/jobs/{job_id}/result", "get", early) == []
    done = embedded_client.wait_finished(job["id"])
    assert done["status"] in ("succeeded", "failed"), done

    result = embedded_client.http.get(f"/v1/jobs/{job['id']}/result")
    assert result.status_code == 200
    assert result.headers["content-type"] == "application/json"
    assert _documented(schemas, "/v1/jobs/{job_id}/result", "get", result) == []
    body = result.json()
    assert body["trajectory"]["nodes"] == 40
    assert body["history"]

    history = embedded_client.http.get(f"/v1/jobs/{job['id']}/history")
    assert history.status_code == 200
    assert _documented(schemas, "/v1/jobs/{job_id}/history", "get", history) == []
    assert history.json()["iterations"] == body["history"]

    # the documented schema is not a formality: a changed body breaks it
    broken = {**body, "timing": {"wall_s": "fast"}}
    assert schemas.errors(broken, schemas.component("ResultDocument"))


@pytest.mark.parametrize("path", ["/v1/jobs", "/v1/problems/validate"])
@pytest.mark.parametrize(
    ("body", "where"),
    [
        (b'{"scenario": ', "Expecting value at line 1, column 14 (character 13)"),
        (b'{"scenario": "\xff"}', "it is not UTF-8 text (invalid start byte at byte 14)"),
        (b"", "Expecting value at line 1, column 1 (character 0)"),
    ],
)
def test_undecodable_bodies_over_http_are_the_documented_400(
    embedded_client: ServiceClient, spec: dict[str, Any], path: str, body: bytes, where: str
) -> None:
    response = embedded_client.http.post(
        path, content=body, headers={"Content-Type": "application/json"}
    )
    assert response.status_code == 400, response.text
    assert response.json()["error"] == {
        "code": "malformed_body",
        "message": f"the body is not valid JSON: {where}",
        "field": None,
    }
    schemas = OpenApiSchemas(spec)
    assert _documented(schemas, path, "post", response) == []
