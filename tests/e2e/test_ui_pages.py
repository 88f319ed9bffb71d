"""The web pages (``/ui/``) in a real headless Chromium driven by Playwright, against a real
``trajopt serve`` (embedded defaults), with no network but the loopback: a finished job's page
shows its plots, verification and links; a running job's page updates as iterations arrive and
shows the end; the list shows the caller's jobs; no page logs a console error or asks any other
host for anything."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from tests.e2e.browser import PageWatch
from tests.integration.harness import (
    ApiServer,
    ServiceClient,
    create_api_key,
    embedded_env,
    long_job,
)

pytestmark = pytest.mark.slow

ZONE_SCENARIO = "rlv-max-terminal-velocity-active-nfz"
AT_LEAST = "n => Number(document.querySelector('#iteration').textContent) >= n"
"""A function (a string expression would be evaluated, which the pages' policy forbids)."""
ROWS_AT_LEAST = "n => document.querySelectorAll('#progress tbody tr').length >= n"
ROWS_AND_COUNTER = """() => [
    document.querySelectorAll('#progress tbody tr').length,
    Number(document.querySelector('#iteration').textContent),
]"""
"""The table's rows and the iteration counter, read together in one turn of the page's event
loop: several iterations can arrive in one chunk between two separate reads."""


def test_a_finished_job_shows_plots_verification_and_links(
    watch: PageWatch, embedded_server: ApiServer, embedded_client: ServiceClient
) -> None:
    job = embedded_client.submit({"scenario": ZONE_SCENARIO})
    assert embedded_client.wait_finished(job["id"])["status"] == "succeeded"
    page = watch.page
    page.goto(f"{embedded_server.base_url}/ui/jobs/{job['id']}")
    page.wait_for_selector("#figures:not([hidden]) figure[data-plot='convergence'] img")
    loaded = "() => [...document.querySelectorAll('#plots img')].every(i => i.naturalWidth)"
    page.wait_for_function(loaded)
    names = page.eval_on_selector_all("#plots figure", "fs => fs.map(f => f.dataset.plot)")
    expected = embedded_client.http.get(f"/v1/jobs/{job['id']}/plots").json()
    assert names == expected
    widths = page.eval_on_selector_all("#plots img", "is => is.map(i => i.naturalWidth)")
    assert widths == [800] * len(expected)
    assert page.inner_text("#status") == "succeeded"
    assert "feasible" in page.inner_text("#verdict")
    checks = page.inner_text("#verification")
    assert "peak heat_rate_W_m2" in checks and "no-fly zone on-path zone" in checks
    assert "fail" not in page.eval_on_selector_all(
        "#verification tbody td:last-child", "cells => cells.map(c => c.textContent).join(' ')"
    )
    assert "max_terminal_velocity" in page.inner_text("#objective")
    assert page.inner_text("#links").split(" · ") == [
        "result JSON",
        "history JSON",
        "trajectory CSV",
    ]
    rows = page.eval_on_selector_all("#progress tbody tr", "rs => rs.length")
    assert rows == len(
        embedded_client.http.get(f"/v1/jobs/{job['id']}/history").json()["iterations"]
    )
    with page.expect_download() as download:
        page.click("#links a:text('trajectory CSV')")
    assert download.value.suggested_filename == f"{job['id']}-trajectory.csv"
    watch.clean()


def test_a_running_job_updates_live_and_shows_its_end(
    watch: PageWatch, embedded_server: ApiServer, embedded_client: ServiceClient
) -> None:
    job = embedded_client.submit(long_job(ZONE_SCENARIO))
    page = watch.page
    try:
        page.goto(f"{embedded_server.base_url}/ui/jobs/{job['id']}")
        page.wait_for_function(AT_LEAST, arg=2, timeout=120_000)
        first_rows, _ = page.evaluate(ROWS_AND_COUNTER)
        page.wait_for_function(ROWS_AT_LEAST, arg=first_rows + 3, timeout=60_000)
        rows, shown = page.evaluate(ROWS_AND_COUNTER)
        assert rows >= first_rows + 3
        assert shown == rows  # the counter names the last row (iterations numbered from 1)
        assert page.inner_text("#status") == "running"
    finally:
        embedded_client.http.delete(f"/v1/jobs/{job['id']}")
    page.wait_for_function(
        "() => document.querySelector('#status').textContent === 'cancelled'", timeout=60_000
    )
    page.wait_for_function(
        "() => document.querySelector('#message').textContent.startsWith('finished')"
    )
    assert "cancelled" in page.inner_text("#failure")
    watch.clean()


def test_a_page_opened_on_a_queued_job_sees_it_start(
    watch: PageWatch, embedded_server: ApiServer, embedded_client: ServiceClient
) -> None:
    """The server has one local worker: a second job waits behind the first until that one is
    cancelled, and its page (opened while it waited) shows it running as its iterations come."""
    ahead = embedded_client.submit(long_job(ZONE_SCENARIO))
    waiting = embedded_client.submit(long_job(ZONE_SCENARIO))
    page = watch.page
    try:
        embedded_client.wait_for(ahead["id"], lambda job: job["status"] == "running", 120, "start")
        page.goto(f"{embedded_server.base_url}/ui/jobs/{waiting['id']}")
        page.wait_for_function("() => document.querySelector('#status').textContent !== 'loading'")
        assert page.inner_text("#status") == "queued"
        embedded_client.http.delete(f"/v1/jobs/{ahead['id']}")
        page.wait_for_function(ROWS_AT_LEAST, arg=2, timeout=120_000)
        assert page.inner_text("#status") == "running"
    finally:
        embedded_client.http.delete(f"/v1/jobs/{ahead['id']}")
        embedded_client.http.delete(f"/v1/jobs/{waiting['id']}")
    page.wait_for_function(
        "() => document.querySelector('#status').textContent === 'cancelled'", timeout=60_000
    )
    watch.clean()


def test_the_root_address_opens_the_jobs_page_in_a_browser(
    watch: PageWatch, embedded_server: ApiServer, embedded_client: ServiceClient
) -> None:
    """``GET /``: a browser lands on the jobs page (a 307 to ``/ui/``); an API client gets 200
    JSON naming where the API, the docs and the pages are, each of which answers."""
    page = watch.page
    page.goto(f"{embedded_server.base_url}/")
    page.wait_for_selector("#jobs")
    assert page.url == f"{embedded_server.base_url}/ui/"
    watch.clean()
    http = embedded_client.http
    redirect = http.get("/", headers={"Accept": "text/html,*/*;q=0.8"}, follow_redirects=False)
    assert (redirect.status_code, redirect.headers["location"]) == (307, "ui/")
    answer = http.get("/", headers={"Accept": "application/json"})
    assert answer.status_code == 200 and answer.headers["content-type"] == "application/json"
    links = answer.json()["links"]
    assert links["jobs_page"] == "/ui/" and links["openapi"] == "/openapi.json"
    assert answer.json()["service"] == "trajopt"
    assert {name: http.get(path).status_code for name, path in links.items()} == dict.fromkeys(
        links, 200
    )


def test_the_list_links_each_of_the_callers_jobs(
    watch: PageWatch, embedded_server: ApiServer, embedded_client: ServiceClient
) -> None:
    job = embedded_client.submit({"scenario": ZONE_SCENARIO, "method": {"max_iterations": 2}})
    embedded_client.wait_finished(job["id"])
    page = watch.page
    page.goto(f"{embedded_server.base_url}/ui")
    page.wait_for_selector(f"#jobs a[href='jobs/{job['id']}']")
    total = embedded_client.http.get("/v1/jobs").json()["total"]
    assert page.eval_on_selector_all("#jobs tbody tr", "rs => rs.length") == min(total, 50)
    page.click(f"#jobs a[href='jobs/{job['id']}']")
    page.wait_for_selector("#figures:not([hidden])")
    assert page.inner_text("#status") == "failed"
    finished = embedded_client.http.get(f"/v1/jobs/{job['id']}").json()
    error = finished["error"]
    assert page.inner_text("#failure").startswith(error["code"])
    watch.clean()


def test_a_job_left_to_auto_shows_the_method_it_chose(
    watch: PageWatch, embedded_server: ApiServer, embedded_client: ServiceClient
) -> None:
    """A document without a method: the list and the job's page say ``auto → energy-scp``."""
    from worker.solver.scenarios import get_scenario

    document = dict(get_scenario("rlv-min-heat-load").problem)
    document.pop("method")
    job = embedded_client.submit(document)
    assert embedded_client.wait_finished(job["id"])["status"] == "succeeded"
    page = watch.page
    page.goto(f"{embedded_server.base_url}/ui/")
    link = f"#jobs a[href='jobs/{job['id']}']"
    page.wait_for_selector(link)
    cells = page.eval_on_selector(
        link, "a => [...a.closest('tr').children].map(c => c.textContent)"
    )
    assert cells[2] == "auto → energy-scp"
    page.click(link)
    page.wait_for_selector("#figures:not([hidden])")
    assert page.inner_text("#method") == "auto → energy-scp"
    watch.clean()


def test_a_batch_page_follows_its_children_and_shows_its_plot(
    watch: PageWatch, embedded_server: ApiServer, embedded_client: ServiceClient
) -> None:
    body = {
        "name": "zone radius",
        "base": {"scenario": ZONE_SCENARIO, "method": {"nodes": 30}},
        "grid": {"parameters": [{"path": "/no_fly_zones/0/radius_deg", "values": [1.0, 2.0, 3.0]}]},
    }
    answer = embedded_client.http.post("/v1/batches", json=body)
    assert answer.status_code == 202, answer.text
    batch = answer.json()
    page = watch.page
    page.goto(f"{embedded_server.base_url}/ui/batches/{batch['id']}")
    page.wait_for_selector("#figures:not([hidden]) img", timeout=120_000)
    page.wait_for_function("() => document.querySelector('#plots img').naturalWidth === 800")
    assert page.inner_text("#status") == "finished"
    assert page.eval_on_selector_all("#children tbody tr", "rs => rs.length") == 3
    headers = page.eval_on_selector_all("#children th", "hs => hs.map(h => h.textContent)")
    assert headers[:2] == ["child", "/no_fly_zones/0/radius_deg"]
    first_job = embedded_client.http.get(f"/v1/batches/{batch['id']}/summary").json()["rows"][0]
    page.click("#children tbody tr:first-child a")
    page.wait_for_selector("#figures:not([hidden]) figure[data-plot='ground-track'] img")
    assert first_job["job_id"] in page.url
    page.goto(f"{embedded_server.base_url}/ui/")
    page.wait_for_selector(f"#batches a[href='batches/{batch['id']}']")
    watch.clean()


@pytest.fixture(scope="module")
def keyed_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[ApiServer, str]]:
    """An embedded server in api-keys mode and a key of client ``ui``."""
    data = tmp_path_factory.mktemp("keyed")
    env = embedded_env(
        data,
        TRAJOPT_AUTH_MODE="api-keys",
        TRAJOPT_API_KEY_SECRET="ui-test-only-4c1d7e0b9a8f6e5d4c3b2a19",
    )
    key = create_api_key(env, "ui")
    for server in ApiServer(env, data / "serve.log").serving():
        yield server, key


def test_in_api_keys_mode_the_page_asks_for_the_key_once_and_sends_it(
    browser: Any, keyed_server: tuple[ApiServer, str]
) -> None:
    server, key = keyed_server
    owner = ServiceClient(server.base_url, key)
    try:
        job = owner.submit({"scenario": ZONE_SCENARIO, "method": {"max_iterations": 1}})
        owner.wait_finished(job["id"])
    finally:
        owner.close()
    context = browser.new_context()
    try:
        watch = PageWatch(context.new_page(), server.base_url)
        page = watch.page
        page.goto(f"{server.base_url}/ui/")
        page.wait_for_selector("#key-form:not([hidden]) #api-key")
        assert "missing_api_key" in page.inner_text("#message")
        page.fill("#api-key", key)
        page.click("#key-form button")
        page.wait_for_selector(f"#jobs a[href='jobs/{job['id']}']")
        page.click(f"#jobs a[href='jobs/{job['id']}']")
        page.wait_for_selector("#figures:not([hidden]) figure[data-plot='convergence'] img")
        # the 401 of the first try is the one console error a browser logs for a refused fetch
        watch.errors = [e for e in watch.errors if "401" not in e]
        watch.clean()
    finally:
        context.close()
