"""A result to look at over real HTTP (``trajopt serve`` on its embedded defaults): the
trajectory CSV and the plots of a finished job, and their refusals."""

from __future__ import annotations

import csv
import io
import struct
import time
import xml.etree.ElementTree as ET
from typing import Any

import numpy as np
import pytest
from matplotlib.image import imread

from tests.integration.harness import ServiceClient, long_job

pytestmark = pytest.mark.slow

ZONE_SCENARIO = "rlv-max-terminal-velocity-active-nfz"


@pytest.fixture(scope="module")
def finished(embedded_server: Any) -> dict[str, Any]:
    """A succeeded job of the active-zone scenario and its result document."""
    client = embedded_server.client()
    job = client.submit({"scenario": ZONE_SCENARIO})
    assert client.wait_finished(job["id"])["status"] == "succeeded"
    result = client.http.get(f"/v1/jobs/{job['id']}/result").json()
    return {"id": job["id"], "result": result}


def test_trajectory_csv_matches_the_result(
    embedded_client: ServiceClient, finished: dict[str, Any]
) -> None:
    response = embedded_client.http.get(f"/v1/jobs/{finished['id']}/trajectory.csv")
    assert response.status_code == 200
    assert response.headers["content-type"].startswith("text/csv")
    rows = list(csv.reader(io.StringIO(response.text)))
    traj = finished["result"]["trajectory"]
    names = [k for k, v in traj.items() if isinstance(v, list)]
    assert rows[0] == [f"{n} [{traj['units'][n]}]" for n in names]
    assert len(rows) - 1 == traj["nodes"]
    for j, name in enumerate(names):
        assert [float(row[j]) for row in rows[1:]] == traj[name]  # the stored numbers, exactly


def test_plots_are_listed_and_render_as_png_and_svg(
    embedded_client: ServiceClient, finished: dict[str, Any]
) -> None:
    base = f"/v1/jobs/{finished['id']}/plots"
    names = embedded_client.http.get(base).json()
    assert names == [
        "altitude-velocity",
        "ground-track",
        "states",
        "controls",
        "heat-rate",
        "dynamic-pressure",
        "load-factor",
        "convergence",
    ]
    for name in names:
        png = embedded_client.http.get(f"{base}/{name}.png")
        assert png.status_code == 200 and png.headers["content-type"] == "image/png", name
        assert png.content[:8] == b"\x89PNG\r\n\x1a\n"
        assert struct.unpack(">II", png.content[16:24]) == (800, 500)
        svg = embedded_client.http.get(f"{base}/{name}.svg")
        assert svg.headers["content-type"].startswith("image/svg+xml"), name
        assert ET.fromstring(svg.content).tag.endswith("svg")


def test_the_ground_track_shows_the_zone(
    embedded_client: ServiceClient, finished: dict[str, Any]
) -> None:
    png = embedded_client.http.get(f"/v1/jobs/{finished['id']}/plots/ground-track.png").content
    rgb = (imread(io.BytesIO(png))[..., :3] * 255).round()
    # the zone's fill (its red at alpha 0.35 over white, about (241, 180, 180)): a 2-degree
    # zone on a 70-degree-tall map covers some tens of pixels across
    fill = np.all(np.abs(rgb - np.array([241.0, 180.0, 180.0])) <= 8.0, axis=-1)
    assert fill.sum() > 200


def test_refusals_name_what_is_wrong(
    embedded_client: ServiceClient, finished: dict[str, Any]
) -> None:
    base = f"/v1/jobs/{finished['id']}/plots"
    unknown = embedded_client.http.get(f"{base}/footprint.png")
    assert unknown.status_code == 404
    error = unknown.json()["error"]
    assert error["code"] == "plot_not_found" and "ground-track" in error["message"]
    bad_format = embedded_client.http.get(f"{base}/states.jpg")
    assert bad_format.status_code == 404
    assert bad_format.json()["error"]["code"] == "plot_format_not_found"
    running = embedded_client.submit(long_job(ZONE_SCENARIO))
    try:
        early = embedded_client.http.get(f"/v1/jobs/{running['id']}/trajectory.csv")
        assert early.status_code == 409 and early.json()["error"]["code"] == "job_not_finished"
        assert embedded_client.http.get(f"/v1/jobs/{running['id']}/plots").status_code == 409
    finally:
        embedded_client.http.delete(f"/v1/jobs/{running['id']}")


def _renders(client: ServiceClient) -> float:
    """The server's ``trajopt_plot_renders_total``."""
    for line in client.http.get("/metrics").text.splitlines():
        if line.startswith("trajopt_plot_renders_total "):
            return float(line.split()[1])
    raise AssertionError("no trajopt_plot_renders_total in /metrics")


@pytest.mark.exclusive
def test_a_batch_plot_is_kept_until_a_child_changes(embedded_client: ServiceClient) -> None:
    base = long_job(ZONE_SCENARIO)
    grid = {"parameters": [{"path": "/method/max_iterations", "values": [2, 500]}]}
    answer = embedded_client.http.post("/v1/batches", json={"base": base, "grid": grid})
    assert answer.status_code == 202, answer.text
    batch = answer.json()["id"]
    deadline = time.monotonic() + 120
    # the children run in order on the one job process: the first ends, the second runs on
    while set(embedded_client.http.get(f"/v1/batches/{batch}").json()["counts"]) != {
        "failed",
        "running",
    }:
        assert time.monotonic() < deadline, "the second child never ran"
        time.sleep(0.1)
    before = _renders(embedded_client)
    plot = f"/v1/batches/{batch}/plot.png"
    started = time.perf_counter()
    first = embedded_client.http.get(plot)
    rendered_s = time.perf_counter() - started
    started = time.perf_counter()
    again = [embedded_client.http.get(plot).content for _ in range(10)]
    kept_s = time.perf_counter() - started
    assert first.status_code == 200 and again == [first.content] * 10
    assert _renders(embedded_client) == before + 1
    # ten answers of the kept plot cost less than a few renders (each would render once more)
    assert kept_s < 3 * rendered_s, (kept_s, rendered_s)
    assert embedded_client.http.delete(f"/v1/batches/{batch}").status_code == 200
    while embedded_client.http.get(f"/v1/batches/{batch}").json()["status"] == "running":
        assert time.monotonic() < deadline + 60, "the batch was not cancelled"
        time.sleep(0.1)
    assert embedded_client.http.get(plot).status_code == 200  # a child moved: rendered again
    embedded_client.http.get(plot)
    assert _renders(embedded_client) == before + 2
