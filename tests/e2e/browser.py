"""Headless Chromium for the page tests: load a page with no network but loopback, read the DOM
(or drive it with Playwright, :class:`PageWatch` recording its errors and foreign requests).

The browser runs as a plain subprocess (``--dump-dom``): it loads the page, lets its scripts run
for a virtual time budget, prints the rendered DOM and exits. Every host name but 127.0.0.1
resolves to nothing and every other connection goes to a closed proxy port, so a page that
needs a CDN stays blank, as it would on a machine without internet. Chromium's network log
gives every request the page itself made.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tests.integration.harness import require

CANDIDATES = ("chromium", "chromium-browser", "google-chrome")
OFFLINE_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--host-resolver-rules=MAP * ~NOTFOUND , EXCLUDE 127.0.0.1",
    "--proxy-server=127.0.0.1:9",
    "--proxy-bypass-list=127.0.0.1",
)
"""Headless, no background traffic, and nothing reachable but 127.0.0.1."""


def chromium() -> str:
    """The Chromium executable; fails the test when there is none (see ``harness.require``)."""
    for name in CANDIDATES:
        found = shutil.which(name)
        if found:
            return found
    require("Chromium", "no chromium executable on PATH (apt-get install chromium)")
    raise AssertionError("unreachable")


@dataclass(frozen=True)
class RenderedPage:
    """What the browser made of a page: the DOM after its scripts ran, and what it requested."""

    dom: str
    requested: list[str]
    """URLs the page requested (the navigation itself and everything the page loaded)."""


def _page_requests(net_log: Path) -> list[str]:
    """URLs of the requests in a Chromium net log started by the page or its navigation."""
    log = json.loads(net_log.read_text(encoding="utf-8"))
    types = {number: name for name, number in log["constants"]["logEventTypes"].items()}
    urls: list[str] = []
    for event in log["events"]:
        params = event.get("params", {})
        if types.get(event["type"]) != "URL_REQUEST_START_JOB" or "url" not in params:
            continue
        initiator = params.get("initiator")
        if initiator is None or initiator.startswith("http://127.0.0.1"):
            urls.append(params["url"])
    return urls


def render(url: str, budget_ms: int = 10_000, timeout_s: float = 120.0) -> RenderedPage:
    """Load ``url`` offline in headless Chromium and return the rendered DOM and the requests."""
    executable = chromium()
    with tempfile.TemporaryDirectory(prefix="chromium-") as tmp:
        net_log = Path(tmp) / "net-log.json"
        args = [
            executable,
            *OFFLINE_FLAGS,
            f"--user-data-dir={Path(tmp) / 'profile'}",
            f"--log-net-log={net_log}",
            "--dump-dom",
            f"--virtual-time-budget={budget_ms}",
            url,
        ]
        env = {**os.environ, "HOME": tmp}
        done = subprocess.run(
            args, capture_output=True, text=True, timeout=timeout_s, env=env, check=False
        )
        assert done.returncode == 0, f"chromium exited {done.returncode}:\n{done.stderr[-3000:]}"
        return RenderedPage(dom=done.stdout, requested=_page_requests(net_log))


class PageWatch:
    """A Playwright page with every console error, page error and foreign request recorded."""

    def __init__(self, page: Any, base_url: str) -> None:
        self.page = page
        self.errors: list[str] = []
        self.foreign: list[str] = []
        page.on(
            "console",
            lambda msg: self.errors.append(f"console: {msg.text}") if msg.type == "error" else None,
        )
        page.on("pageerror", lambda exc: self.errors.append(f"page error: {exc}"))
        page.on(
            "request",
            lambda req: (
                None
                if req.url.startswith((f"{base_url}/", "blob:", "data:"))
                else self.foreign.append(req.url)
            ),
        )

    def clean(self) -> None:
        assert self.errors == [], self.errors
        assert self.foreign == [], self.foreign
