"""A ``trajopt serve`` on its embedded defaults (SQLite, local pool) shared by the e2e tests."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.e2e.browser import OFFLINE_FLAGS, PageWatch, chromium
from tests.integration.harness import ApiServer, ServiceClient, embedded_env


@pytest.fixture(scope="session")
def embedded_data_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The data folder (SQLite file) of :func:`embedded_server`."""
    return tmp_path_factory.mktemp("embedded-contract")


@pytest.fixture(scope="session")
def embedded_server(embedded_data_dir: Path) -> Iterator[ApiServer]:
    """One embedded server for the session's contract, docs and override tests."""
    env = embedded_env(embedded_data_dir)
    yield from ApiServer(env, embedded_data_dir / "serve.log").serving()


@pytest.fixture
def embedded_client(embedded_server: ApiServer) -> Iterator[ServiceClient]:
    """An HTTP client of :func:`embedded_server`."""
    yield from embedded_server.serving_client()


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """Headless Chromium under Playwright, offline but for the loopback."""
    sync_api = pytest.importorskip("playwright.sync_api")
    executable = chromium()
    flags = [flag for flag in OFFLINE_FLAGS if flag != "--headless"]
    with sync_api.sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=executable, args=flags)
        yield launched
        launched.close()


@pytest.fixture
def watch(browser: Any, embedded_server: ApiServer) -> Iterator[PageWatch]:
    """A fresh page of :func:`browser` on :func:`embedded_server`, its errors recorded."""
    context = browser.new_context()
    yield PageWatch(context.new_page(), embedded_server.base_url)
    context.close()
