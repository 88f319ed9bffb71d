"""``/docs`` and ``/redoc`` render in a real browser that has no network but the loopback.

A real ``trajopt serve`` (embedded defaults) and headless Chromium: the pages must draw the
operations of the OpenAPI document, which they can only do if their scripts came from this
server, and must request nothing from any other host (fonts, images, scripts), not even one
their Content-Security-Policy would block (the browser logs that as a console error).
"""

from __future__ import annotations

import re

import pytest

from tests.e2e.browser import PageWatch, render
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


@pytest.mark.parametrize(("path", "drawn"), [("/redoc", "Submit a job"), ("/docs", "/v1/jobs")])
def test_the_docs_pages_log_no_error_and_ask_no_other_host(
    watch: PageWatch, embedded_server: ApiServer, path: str, drawn: str
) -> None:
    page = watch.page
    page.goto(f"{embedded_server.base_url}{path}")
    page.get_by_text(drawn).first.wait_for(state="attached")
    page.wait_for_load_state("networkidle")
    watch.clean()
