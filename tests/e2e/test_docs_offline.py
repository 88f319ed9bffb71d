"""``/docs`` and ``/redoc`` render in a real browser that has no network but the loopback.

A real ``trajopt serve`` (embedded defaults) and headless Chromium: the pages must draw the
operations of the OpenAPI document, which they can only do if their scripts came from this
server, and must request nothing from any other host (fonts, images, scripts).
"""

from __future__ import annotations

import re

import pytest

from tests.e2e.browser import render
from tests.integration.harness import ApiServer

pytestmark = pytest.mark.slow


def _foreign(requested: list[str], server: ApiServer) -> list[str]:
    return [url for url in requested if not url.startswith(f"{server.base_url}/")]


def test_swagger_ui_renders_every_operation_offline(embedded_server: ApiServer) -> None:
    page = render(f"{embedded_server.base_url}/docs")
    assert re.search(r'class="opblock opblock-post[^"]*"', page.dom), page.dom[:2000]
    paths = set(re.findall(r'class="opblock-summary-path" data-path="([^"]+)"', page.dom))
    assert {"/v1/jobs", "/v1/jobs/{job_id}/result", "/v1/problems/validate"} <= paths
    assert f"{embedded_server.base_url}/openapi.json" in page.requested
    assert _foreign(page.requested, embedded_server) == []


def test_redoc_renders_every_operation_offline(embedded_server: ApiServer) -> None:
    page = render(f"{embedded_server.base_url}/redoc")
    for summary in ("Submit a job", "Fetch the result document", "Validate a problem"):
        assert summary in page.dom, page.dom[:2000]
    assert "operation/get_result" in page.dom
    assert "ProblemDocument" in page.dom  # the body schema that app.openapi fills in
    assert f"{embedded_server.base_url}/openapi.json" in page.requested
    assert _foreign(page.requested, embedded_server) == []
