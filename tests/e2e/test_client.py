"""``app.client.TrajoptClient`` and ``trajopt submit`` against real ``trajopt serve`` processes
(embedded defaults): every call of the client on a live job, its typed errors, its retries of a
rate-limited service after the Retry-After the service sends, and the command line on top."""

from __future__ import annotations

import csv
import hashlib
import io
import json
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from app.client import ConflictError, InvalidRequestError, NotFoundError, TrajoptClient
from tests.integration.harness import ApiServer, embedded_env, long_job, service_free_env

pytestmark = pytest.mark.slow

SCENARIO = "rlv-max-terminal-velocity-active-nfz"


@pytest.fixture
def client(embedded_server: ApiServer) -> Iterator[TrajoptClient]:
    with TrajoptClient(embedded_server.base_url) as made:
        yield made


def test_submit_follow_wait_and_fetch(client: TrajoptClient) -> None:
    job = client.submit_scenario(
        SCENARIO,
        overrides={"path_constraints": {"load_factor": {"max_g": 2.4}}},
        method={"nodes": 30},
    )
    assert job["status"] == "queued"
    records = list(client.iterations(job["id"], timeout_s=120))
    assert [r["iteration"] for r in records] == list(range(1, len(records) + 1))
    done = client.wait(job["id"], timeout_s=60)
    assert done["status"] == "succeeded"
    result = client.result(job["id"])
    assert result["provenance"]["method_options"]["nodes"] == 30
    assert result["verification"]["path_maxima"]["load_factor_g"]["limit"] == 2.4
    assert len(client.history(job["id"])) == len(result["history"])
    rows = list(csv.reader(io.StringIO(client.trajectory_csv(job["id"]))))
    assert len(rows) == 1 + 30
    assert "ground-track" in client.plots(job["id"])
    assert client.plot(job["id"], "ground-track", "svg").lstrip().startswith(b"<?xml")
    assert job["id"] in [j["id"] for j in client.jobs(status="succeeded", page_size=2)]


def test_typed_errors_and_cancel(client: TrajoptClient) -> None:
    with pytest.raises(InvalidRequestError) as invalid:
        client.submit_scenario(
            SCENARIO, overrides={"vehicle": {"mass_kg": -1}}, method={"nodes": 1}
        )
    assert set(invalid.value.fields) == {"vehicle.mass_kg", "method.nodes"}
    with pytest.raises(NotFoundError):
        client.job("4b0c3e1e-0000-4000-8000-000000000000")
    running = client.submit(long_job(SCENARIO))
    with pytest.raises(ConflictError) as early:
        client.result(running["id"])
    assert early.value.code == "job_not_finished"
    client.cancel(running["id"])
    assert client.wait(running["id"], timeout_s=60)["status"] == "cancelled"
    same = client.submit({"scenario": SCENARIO}, idempotency_key="once")
    assert client.submit({"scenario": SCENARIO}, idempotency_key="once")["id"] == same["id"]


def test_batches_of_methods_and_of_dispersions(client: TrajoptClient) -> None:
    methods = client.submit_batch(
        {
            "base": {"scenario": "rlv-max-terminal-velocity", "method": {"nodes": 30}},
            "methods": [
                {"name": "foh-ptr", "nodes": 30},
                {"name": "foh-ptr", "nodes": 30, "grid": "uniform"},
            ],
        }
    )
    assert client.wait_batch(methods["id"], timeout_s=180)["status"] == "finished"
    rows = client.batch_summary(methods["id"])["rows"]
    assert [r["parameters"]["/method"] for r in rows] == ["foh-ptr", "foh-ptr"]
    assert all(r["status"] == "succeeded" for r in rows), rows
    # one problem, two grids: the same answer within 0.3 % (the variant suite's band)
    assert rows[1]["objective"] == pytest.approx(rows[0]["objective"], rel=3e-3)
    assert client.batch_plot(methods["id"])[:4] == b"\x89PNG"
    spread = {
        "base": {"scenario": SCENARIO, "method": {"max_iterations": 1}},
        "monte_carlo": {
            "samples": 3,
            "seed": 5,
            "dispersions": [
                {"path": "/initial_state/velocity_m_s", "distribution": "normal", "sigma": 10}
            ],
        },
    }
    first, again = client.submit_batch(spread), client.submit_batch(spread)
    drawn = [
        [r["parameters"] for r in client.batch_summary(b["id"])["rows"]] for b in (first, again)
    ]
    assert drawn[0] == drawn[1] and len({json.dumps(p) for p in drawn[0]}) == 3  # reproducible
    for batch in (first, again):
        client.cancel_batch(batch["id"])
        assert client.wait_batch(batch["id"], timeout_s=120)["status"] in ("finished", "cancelled")


def test_a_footprint_holds_the_base_problems_own_terminal_point(client: TrajoptClient) -> None:
    batch = client.submit_batch(
        {
            "base": {"scenario": "rlv-max-terminal-velocity"},
            "footprint": {"longitudes_deg": [6, 12, 18]},
        }
    )
    assert client.wait_batch(batch["id"], timeout_s=240)["status"] == "finished"
    rows = client.batch_summary(batch["id"])["rows"]
    assert [r["status"] for r in rows] == ["succeeded"] * 6, rows
    edges = {
        (r["parameters"]["/terminal/longitude_deg"], r["parameters"]["/objective"]): r for r in rows
    }
    top, bottom = edges[(12, "max_final_latitude")], edges[(12, "min_final_latitude")]
    # case 1 itself flies to 12 deg E, 70 deg N: inside its own footprint (measured 65.6 .. 76.0)
    assert bottom["final_latitude_deg"] < 70.0 < top["final_latitude_deg"]
    for row in rows:  # each child flew to its own final longitude
        assert row["final_longitude_deg"] == pytest.approx(
            row["parameters"]["/terminal/longitude_deg"], abs=0.1
        )
    assert client.batch_plot(batch["id"], "svg").lstrip().startswith(b"<?xml")


def test_a_chained_batch_starts_each_child_from_a_finished_sibling(client: TrajoptClient) -> None:
    limits = [1.5e6, 1.48e6, 1.46e6, 1.44e6]
    batch = client.submit_batch(
        {
            "base": {"scenario": "rlv-max-terminal-velocity"},
            "grid": {
                "parameters": [{"path": "/path_constraints/heat_rate/max_W_m2", "values": limits}]
            },
            "chain": True,
        }
    )
    assert client.wait_batch(batch["id"], timeout_s=240)["status"] == "finished"
    rows = client.batch_summary(batch["id"])["rows"]
    assert [r["status"] for r in rows] == ["succeeded"] * 4, rows
    results = [client.result(r["job_id"]) for r in rows]
    # one local worker: the children run in order, the first from the method's own guess
    assert "initial_guess" not in results[0]["provenance"]
    for row, result in zip(rows[1:], results[1:], strict=True):
        assert result["provenance"]["initial_guess"] == "the given trajectory (40 points)"
        assert result["timing"]["iterations"] <= 0.75 * results[0]["timing"]["iterations"]
        solved = client.problem(row["job_id"])  # with the sibling's start it was given
        assert result["provenance"]["source_job"] == solved["initial_guess"]["from_job"]
        canonical = json.dumps(solved, sort_keys=True, separators=(",", ":")).encode()
        assert result["provenance"]["problem_sha256"] == hashlib.sha256(canonical).hexdigest()


def test_a_job_starts_from_an_earlier_job(client: TrajoptClient) -> None:
    first = client.submit_scenario("rlv-max-terminal-velocity")
    assert client.wait(first["id"], timeout_s=120)["status"] == "succeeded"
    heat = {"path_constraints": {"heat_rate": {"max_W_m2": 1.45e6}}}
    warm = client.submit_scenario(
        "rlv-max-terminal-velocity",
        overrides={**heat, "initial_guess": {"from_job": first["id"]}},
    )
    assert client.wait(warm["id"], timeout_s=120)["status"] == "succeeded"
    result = client.result(warm["id"])
    assert result["provenance"]["initial_guess"] == "the given trajectory (40 points)"
    assert result["timing"]["iterations"] < 20  # measured 4 (36 from the method's own guess)
    with pytest.raises(NotFoundError) as unknown:
        client.submit_scenario(
            SCENARIO,
            overrides={"initial_guess": {"from_job": "4b0c3e1e-0000-4000-8000-000000000000"}},
        )
    assert unknown.value.field == "initial_guess.from_job"
    # a job cancelled while it waits behind another (the pool runs one at a time) ends with no
    # trajectory; one cancelled while it iterates keeps its last iterate, a usable start
    running = client.submit(long_job(SCENARIO))
    queued = client.submit(long_job(SCENARIO))
    client.cancel(queued["id"])
    client.cancel(running["id"])
    assert client.wait(queued["id"], timeout_s=60)["status"] == "cancelled"
    client.wait(running["id"], timeout_s=60)
    with pytest.raises(InvalidRequestError) as empty:
        client.submit_scenario(SCENARIO, overrides={"initial_guess": {"from_job": queued["id"]}})
    assert empty.value.fields == ["initial_guess.from_job"]


@pytest.fixture(scope="module")
def limited(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ApiServer]:
    """A server that takes one submission per client every 2 s."""
    data = tmp_path_factory.mktemp("limited")
    env = embedded_env(data, TRAJOPT_RATE_WINDOW_S="2", TRAJOPT_RATE_SUBMIT_PER_WINDOW="1")
    yield from ApiServer(env, data / "serve.log").serving()


def test_a_rate_limited_submission_is_retried_after_retry_after(limited: ApiServer) -> None:
    body = {"scenario": SCENARIO, "method": {"max_iterations": 1}}
    with TrajoptClient(limited.base_url) as client:
        first = client.submit(body)
        refused = client.http.post("/v1/jobs", json=body)  # what the client meets next
        assert refused.status_code == 429 and float(refused.headers["retry-after"]) > 0
        started = time.monotonic()
        second = client.submit(body)  # waits out the window, then is taken
        assert time.monotonic() - started >= 0.5
        assert second["id"] != first["id"]


def test_trajopt_submit_waits_and_writes_the_result(
    embedded_server: ApiServer, tmp_path: Path
) -> None:
    command = [sys.executable, "-m", "app.cli", "submit", SCENARIO, "--nodes", "30", "--wait"]
    command += ["--server", embedded_server.base_url, "-o", "result.json", "--csv", "t.csv"]
    done = subprocess.run(
        command, cwd=tmp_path, env=service_free_env(), capture_output=True, text=True, timeout=180
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1].endswith("succeeded")
    assert "iteration 1:" in done.stderr
    result = json.loads((tmp_path / "result.json").read_text())
    assert result["status"] == "succeeded"
    assert len((tmp_path / "t.csv").read_text().splitlines()) == 1 + 30
    bad = subprocess.run(
        [*command[:5], "--server", embedded_server.base_url, "--nodes", "1"],
        cwd=tmp_path,
        env=service_free_env(),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert bad.returncode == 2 and "method.nodes" in bad.stderr and "Traceback" not in bad.stderr
    gone = subprocess.run(
        [*command[:5], "--server", "http://127.0.0.1:9", "--retries", "1"],
        cwd=tmp_path,
        env=service_free_env(),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert gone.returncode == 2 and "cannot reach http://127.0.0.1:9 after 2 tries" in gone.stderr
