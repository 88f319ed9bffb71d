"""Every command and example of README.md, docs/problem-contract.md and docs/service.md, run as
documented, with the outcome the documents state.

The blocks are read from the Markdown (tests/e2e/docblocks.py); each case takes its block by its
first line and runs that text, localized: ``.venv/bin/`` becomes this interpreter's folder (and
leads ``PATH``, for a bare ``trajopt``), ``localhost:8000`` the module's server, ``<id>`` one of
its jobs; commands run in a scratch folder. A block no case knows fails
:func:`test_every_block_has_a_case`: a new example in the documents needs its test.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import psycopg
import pytest
import redis

from tests.e2e.docblocks import REPO_ROOT, all_blocks, block
from tests.integration.harness import (
    ApiServer,
    ServiceClient,
    ServiceProcess,
    admin_postgres_url,
    embedded_env,
    forget_queue,
    free_port,
    require,
    service_free_env,
)

pytestmark = pytest.mark.slow

BIN = Path(sys.executable).parent
"""The test environment's ``bin`` folder: the documents' ``.venv/bin``."""
README = "README.md"
CONTRACT = "docs/problem-contract.md"
SERVICE = "docs/service.md"


# --- running what the documents say ---------------------------------------------------------


@dataclass(frozen=True)
class Shell:
    """A finished shell command."""

    code: int
    out: str
    err: str


@dataclass(frozen=True)
class Http:
    """A finished ``curl`` command: its status, headers and body."""

    status: int
    headers: dict[str, str]
    body: str

    def json(self) -> Any:
        """The body as JSON."""
        return json.loads(self.body)


def command_env(**extra: str) -> dict[str, str]:
    """The environment of a documented command: no service settings of the calling shell,
    this interpreter's folder first on ``PATH``, the repository importable."""
    env = service_free_env(**extra)
    env["PATH"] = f"{BIN}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO_ROOT), env.get("PYTHONPATH")) if p)
    return env


def localize(text: str, base_url: str = "", job_id: str = "") -> str:
    """``text`` as it runs here: this environment's ``bin``, this module's server, a job."""
    text = text.replace(".venv/bin/", f"{BIN}/")
    if base_url:
        text = text.replace("http://127.0.0.1:8000", base_url)
        text = text.replace("localhost:8000", base_url.removeprefix("http://"))
    if job_id:
        text = text.replace("<id>", job_id)
    return text


def commands(text: str) -> list[str]:
    """The commands of a shell block: comment lines dropped, continued lines joined (a line
    ending in a backslash or inside an open single quote), ``a ; b`` split."""
    found: list[str] = []
    pending = ""
    for line in text.splitlines():
        if not pending and (not line.strip() or line.lstrip().startswith("#")):
            continue
        pending = f"{pending}\n{line}" if pending else line
        if pending.endswith("\\") or pending.count("'") % 2:
            continue
        found.extend(part.strip() for part in pending.split(" ; "))
        pending = ""
    assert not pending, pending
    return found


def sh(command: str, cwd: Path, env: dict[str, str] | None = None, timeout: float = 180) -> Shell:
    """Run ``command`` with bash in ``cwd``."""
    done = subprocess.run(
        ["bash", "-c", command],
        cwd=cwd,
        env=env or command_env(),
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )
    return Shell(done.returncode, done.stdout, done.stderr)


def curl(command: str, cwd: Path, env: dict[str, str] | None = None) -> Http:
    """Run a documented ``curl`` command, its response headers written aside."""
    assert command.startswith("curl "), command
    assert shutil.which("curl"), "the documents' HTTP examples need curl on PATH"
    headers_file = cwd / f"headers-{uuid.uuid4().hex}.txt"
    run = sh(f"curl -D {headers_file} {command[5:]}", cwd, env)
    assert run.code == 0, (command, run.err)
    lines = headers_file.read_text(encoding="utf-8").splitlines()
    status = int(lines[0].split()[1])
    headers = {}
    for line in lines[1:]:
        name, sep, value = line.partition(":")
        if sep:
            headers[name.strip().lower()] = value.strip()
    return Http(status, headers, run.out)


def words(text: str) -> str:
    """``text`` with every run of white space one space (a message as wrapped in a document)."""
    return " ".join(text.split())


# --- fixtures -----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ApiServer]:
    """README's ``.venv/bin/trajopt serve`` on embedded defaults, on a free port."""
    data = tmp_path_factory.mktemp("documented-serve")
    api = ApiServer(embedded_env(data), data / "serve.log")
    api.args = [str(BIN / "trajopt"), *api.args[2:]]  # the installed command, not -m app.cli
    yield from api.serving()


@pytest.fixture
def client(server: ApiServer) -> Iterator[ServiceClient]:
    """An HTTP client of :func:`server`."""
    yield from server.serving_client()


@pytest.fixture
def finished_job(client: ServiceClient) -> str:
    """A succeeded job of README's scenario on :func:`server`."""
    job = client.submit({"scenario": "rlv-min-heat-load", "method": {"nodes": 61}})
    assert client.wait_finished(job["id"])["status"] == "succeeded"
    return str(job["id"])


# --- the index ------------------------------------------------------------------------------

INSTALL = "python3 -m venv .venv && .venv/bin/pip install"
SOLVE = ".venv/bin/trajopt scenarios"
LOOK = ".venv/bin/trajopt solve rlv-max-terminal-velocity-active-nfz"
LIBRARY = "from app.schemas import ProblemDocument"
CLIENT = "from app.client import TrajoptClient"
SUBMIT = (
    "trajopt submit rlv-min-heat-load --server http://127.0.0.1:8000 --wait -o result.json "
    "--csv result.csv"
)
PROBLEM = "trajopt problem <id> --server ..."
BATCH = "curl -s -X POST localhost:8000/v1/batches"
TOUR = "# submit a built-in scenario"
OVERRIDES = (
    '{"scenario": "rlv-max-terminal-velocity", "overrides": {"method": {"nodes": 60}, "planet": '
    '{"atmosphere": {"model": "us76"}}}}'
)
INFEASIBLE = (
    "infeasible before any iteration: the heat-rate limit 1 000 kW/m^2 is below the first "
    "heat-rate peak of full lift-up flight, 1 108 kW/m^2 (at t = 247 s, 71.5 km, 7229 m/s): no "
    "bank profile can hold it"
)
ADVICE = "raise path_constraints.heat_rate.max_W_m2 above 1.108e+06 ..."
PLOT = "GET /v1/jobs/<id>/plots/<name>.png"
MONTE_CARLO = '"monte_carlo": {"samples": 50, "seed": 7, "dispersions": [...]}'
METHODS = '"methods": [{"name": "foh-ptr"}, ...]'
FROM_JOB = '"initial_guess": {"from_job": "<id>"}'
STACK = "export DATABASE_URL="
KEYS = "export TRAJOPT_AUTH_MODE=api-keys"
MIN_HEAT_LOAD = '{"name": "rlv-min-heat-load",'
TWO_PHASES = '{"name": "shuttle-skip-min-propellant",'
ERRORS = '{"error": {"code": "invalid_problem"'

CASES = {
    (README, INSTALL): "test_install_and_serve",
    (README, "bash .ci/run"): "test_ci_run",
    (README, SOLVE): "test_solve_without_the_service",
    (README, LIBRARY): "test_library",
    (README, LOOK): "test_look_at_a_result",
    (README, "GET /v1/jobs/<id>/trajectory.csv"): "test_result_over_http",
    (README, "GET /v1/jobs/<id>/plots"): "test_result_over_http",
    (README, PLOT): "test_result_over_http",
    (README, "GET /v1/methods"): "test_api_tour",
    (README, CLIENT): "test_python_client",
    (README, SUBMIT): "test_submit_and_problem_from_a_shell",
    (README, PROBLEM): "test_submit_and_problem_from_a_shell",
    (README, BATCH): "test_batch",
    (README, TOUR): "test_api_tour",
    (README, MONTE_CARLO): "test_other_batches",
    (README, METHODS): "test_other_batches",
    (README, FROM_JOB): "test_start_from_an_earlier_job",
    (README, OVERRIDES): "test_overrides",
    (README, INFEASIBLE): "test_infeasible_before_any_iteration",
    (README, ADVICE): "test_infeasible_before_any_iteration",
    (README, STACK): "test_redis_postgresql_and_separate_workers",
    (README, KEYS): "test_keys",
    (CONTRACT, INFEASIBLE[:40]): "test_infeasible_before_any_iteration",
    (CONTRACT, MIN_HEAT_LOAD): "test_solve_without_the_service",
    (CONTRACT, TWO_PHASES): "test_two_phase_example",
    (SERVICE, STACK): "test_redis_postgresql_and_separate_workers",
    (SERVICE, ERRORS): "test_error_shape",
}
"""Each block's case, by the block's document and the start of its text."""

NOT_RUN = {
    (SERVICE, "client ──HTTP──> API"): "a diagram of the service, not a command",
    (SERVICE, 'export POSTGRES_PASSWORD="$(openssl rand -hex 24)"'): (
        "needs a Docker daemon with compose and an image build (minutes); the compose file is "
        "checked by tests/unit/test_service_compose.py"
    ),
    (SERVICE, "python -m bench."): "a benchmark (minutes of CPU); its output is recorded beside it",
}
"""Blocks no test runs, each with the reason."""


def test_every_block_has_a_case() -> None:
    """Every block of the documents is run by a case (or listed in :data:`NOT_RUN` with its
    reason), and every case's block is still in its document."""
    known = CASES.keys() | NOT_RUN.keys()
    blocks = all_blocks()
    unknown = [b for b in blocks if not any(b.matches(*key) for key in known)]
    assert not unknown, "blocks without a test:\n" + "\n".join(
        f"{b.document}:{b.line}: {b.text[:80]}" for b in unknown
    )
    named = {key: sum(b.matches(*key) for b in blocks) for key in known}
    stale = [key for key, count in named.items() if count == 0]
    assert not stale, f"cases whose block is gone: {stale}"
    several = [key for key, count in named.items() if count > 1 and key not in NOT_RUN]
    assert not several, f"keys that name more than one block (make them longer): {several}"
    missing = sorted(name for name in set(CASES.values()) if not callable(globals().get(name)))
    assert not missing, missing


# --- README: install, solve, look ----------------------------------------------------------


def test_install_and_serve(server: ApiServer, client: ServiceClient) -> None:
    """The install is the one .ci/run makes (the same constraints file; a fresh environment
    and its downloads cannot be had inside the suite, and .ci/run is that install), and the
    installed ``trajopt serve`` (the module's server) prints the API docs' address and serves
    /docs and /redoc."""
    text = block(README, INSTALL).text
    install = re.search(r"pip install (.+?) && ", text)
    assert install and install.group(1) == "-c constraints.txt -e ."
    ci = (REPO_ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert "-m pip install --quiet -c constraints.txt -e '.[dev,bench]'" in ci
    assert (REPO_ROOT / "constraints.txt").is_file()
    assert 'trajopt = "app.cli:entry"' in (REPO_ROOT / "pyproject.toml").read_text()
    assert text.endswith(" && .venv/bin/trajopt serve")
    assert f"http://127.0.0.1:{server.port}/docs" in server.log_text()
    for page in ("/docs", "/redoc"):
        assert client.http.get(page).status_code == 200, page


def test_ci_run() -> None:
    """``bash .ci/run`` is the suite that runs this test, so it is not run again here; the
    script does what README says: lint, types, the layering, and every test with Redis,
    PostgreSQL and Chromium at hand."""
    assert block(README, "bash .ci/run").text == "bash .ci/run"
    ci = (REPO_ROOT / ".ci" / "run").read_text(encoding="utf-8")
    for step in ('ruff" check .', 'mypy" app worker', 'lint-imports"', "-m pytest", "chromium"):
        assert step in ci, step
    services = (REPO_ROOT / ".ci" / "services").read_text(encoding="utf-8").lower()
    assert ". .ci/services" in ci and "redis" in services and "postgres" in services


def test_solve_without_the_service(tmp_path: Path) -> None:
    """The three commands: the scenario table with sources, a scenario solved and written
    (summary on stdout, progress on stderr), and a problem document (the contract's example)
    with ``--nodes 201``."""
    from worker.solver.scenarios import list_scenarios

    example = block(CONTRACT, MIN_HEAT_LOAD).text
    (tmp_path / "my-problem.json").write_text(example, encoding="utf-8")
    listing, scenario, document = commands(localize(block(README, SOLVE).text))
    run = sh(listing, tmp_path)
    assert run.code == 0, run.err
    for name in (s.name for s in list_scenarios()):
        assert re.search(rf"^{re.escape(name)} ", run.out, re.M), name
    assert "source: " in run.out

    run = sh(scenario, tmp_path)
    assert run.code == 0, run.err
    assert run.out.startswith("status: succeeded\n") and "verification feasible: True" in run.out
    assert re.search(r"^iter +\d+ +objective", run.err, re.M)
    result = json.loads((tmp_path / "result.json").read_text(encoding="utf-8"))
    assert (result["status"], result["verification"]["feasible"]) == ("succeeded", True)

    assert document.split("#")[0].split()[-2:] == ["--nodes", "201"]
    run = sh(document, tmp_path)
    assert run.code == 0, run.err
    assert run.out.startswith("status: succeeded\n")


def test_library(tmp_path: Path) -> None:
    """The library example prints ``succeeded``, the objective and ``True``."""
    run = subprocess.run(
        [sys.executable, "-c", block(README, LIBRARY).text],
        cwd=tmp_path,
        env=command_env(),
        capture_output=True,
        text=True,
        timeout=180,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    status, objective, feasible = run.stdout.split()
    assert (status, feasible) == ("succeeded", "True")
    assert 7.0e8 < float(objective) < 7.6e8  # J/m^2: the scenario's heat load, not a fit


def test_look_at_a_result(tmp_path: Path) -> None:
    """A scenario solved to JSON and CSV, then plotted as PNG (and, with ``--format svg``, as
    SVG): README's two plots among them."""
    text = block(README, LOOK).text
    solve, plot = commands(localize(text))
    run = sh(solve, tmp_path)
    assert run.code == 0, run.err
    with (tmp_path / "result.csv").open(encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) >= 40, len(rows)
    run = sh(plot, tmp_path)
    assert run.code == 0, run.err
    pngs = {p.stem for p in (tmp_path / "plots").glob("*.png")}
    shown = set(re.findall(r"\]\(docs/images/([\w-]+)\.png\)", readme_text()))
    assert shown == {"heat-rate", "ground-track"} and shown <= pngs, (shown, pngs)
    assert all((REPO_ROOT / "docs" / "images" / f"{name}.png").is_file() for name in shown)
    assert "--format svg for SVG" in text
    run = sh(f"{plot.split('#')[0].strip()} --format svg", tmp_path)
    assert run.code == 0, run.err
    assert {p.stem for p in (tmp_path / "plots").glob("*.svg")} == pngs


def test_result_over_http(client: ServiceClient, finished_job: str) -> None:
    """A job's trajectory as CSV, the names of its plots, and one plot as PNG and as SVG."""
    csv_path = block(README, "GET /v1/jobs/<id>/trajectory.csv").text.removeprefix("GET ")
    response = client.http.get(localize(csv_path, job_id=finished_job))
    assert response.status_code == 200 and response.headers["content-type"].startswith("text/csv")
    plots_path = block(README, "GET /v1/jobs/<id>/plots").text.removeprefix("GET ")
    names = client.http.get(localize(plots_path, job_id=finished_job)).json()
    assert "heat-rate" in json.dumps(names), names
    template = block(README, PLOT).text.removeprefix("GET ")
    for fmt, magic in (("png", b"\x89PNG"), ("svg", b"<")):
        path = localize(template, job_id=finished_job).replace("<name>.png", f"heat-rate.{fmt}")
        response = client.http.get(path, timeout=120)
        assert response.status_code == 200, (path, response.text[:200])
        assert response.content.lstrip().startswith(magic), path


# --- README: from Python, from a shell, batches, the API tour ---------------------------------


def test_python_client(server: ApiServer, tmp_path: Path) -> None:
    """The client example prints one line per iteration (numbered from 1), then ``succeeded``
    and the objective."""
    run = subprocess.run(
        [sys.executable, "-c", localize(block(README, CLIENT).text, server.base_url)],
        cwd=tmp_path,
        env=command_env(),
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    lines = run.stdout.splitlines()
    iterations = [int(line.split()[0]) for line in lines[:-1]]
    assert iterations and iterations == list(range(1, len(iterations) + 1)), run.stdout
    status, objective = lines[-1].split()
    assert status == "succeeded" and 7.0e8 < float(objective) < 7.6e8


def test_submit_and_problem_from_a_shell(server: ApiServer, tmp_path: Path) -> None:
    """``trajopt submit ... --wait`` writes the result and the CSV and exits 0; ``trajopt
    problem <id>`` prints the problem that job solved (its fingerprint the result's)."""
    run = sh(localize(block(README, SUBMIT).text, server.base_url), tmp_path, timeout=300)
    assert run.code == 0, run.err
    result = json.loads((tmp_path / "result.json").read_text(encoding="utf-8"))
    assert result["status"] == "succeeded"
    assert (tmp_path / "result.csv").read_text(encoding="utf-8").count("\n") > 10
    printed = re.search(r"^job (\S+) succeeded", run.out, re.M)
    assert printed, run.out
    job_id = printed.group(1)
    command = localize(block(README, PROBLEM).text, job_id=job_id)
    run = sh(command.replace("...", server.base_url), tmp_path)
    assert run.code == 0, run.err
    canonical = json.dumps(json.loads(run.out), sort_keys=True, separators=(",", ":"))
    assert hashlib.sha256(canonical.encode()).hexdigest() == result["provenance"]["problem_sha256"]


def wait_batch(client: ServiceClient, batch_id: str, timeout: float = 600) -> dict[str, Any]:
    """Poll the batch until it is no longer running."""
    deadline = time.monotonic() + timeout
    while (batch := client.http.get(f"/v1/batches/{batch_id}").json())["status"] == "running":
        assert time.monotonic() < deadline, batch
        time.sleep(0.5)
    return dict(batch)


def test_batch(server: ApiServer, client: ServiceClient, tmp_path: Path) -> None:
    """The grid batch: 202 with six children; once finished, its summary as CSV (a row per
    child, a column per parameter path) and its plot."""
    text = block(README, BATCH).text
    submit, summary = commands(localize(text, server.base_url))
    response = curl(submit, tmp_path)
    assert response.status == 202, response.body
    batch = response.json()
    assert (batch["kind"], batch["size"]) == ("grid", 6)
    done = wait_batch(client, batch["id"])
    assert done["status"] == "finished", done
    response = curl(summary.replace("<id>", batch["id"]), tmp_path)
    assert response.status == 200, response.body
    rows = list(csv.DictReader(response.body.splitlines()))
    assert len(rows) == 6, response.body
    assert {"/no_fly_zones/0/radius_deg", "/path_constraints/heat_rate/max_W_m2"} <= set(rows[0])
    assert "also /plot.png" in text
    plot = client.http.get(f"/v1/batches/{batch['id']}/plot.png", timeout=120)
    assert plot.status_code == 200 and plot.content.startswith(b"\x89PNG")


def member(key: str, **fill: Any) -> dict[str, Any]:
    """README's request member ``key`` as JSON, each ``...`` of it replaced: a list's
    ``[...]`` by ``fill["list"]``, a trailing ``, ...`` dropped."""
    text = block(README, key).text.replace(", ...]", "]")
    if "list" in fill:
        text = text.replace("[...]", json.dumps(fill["list"]))
    parsed: dict[str, Any] = json.loads("{" + text + "}")
    return parsed


def test_other_batches(client: ServiceClient) -> None:
    """README's Monte Carlo dispersion (with one dispersion for its ``[...]``) and method
    comparison are accepted as batches of 50 and of one child (then cancelled: their solves
    are the batch tests' matter, not the README's)."""
    dispersion = {"path": "/initial_state/velocity_m_s", "distribution": "normal", "sigma": 5}
    base = {"scenario": "rlv-max-terminal-velocity"}
    for body, kind, size in (
        ({"base": base, **member(MONTE_CARLO, list=[dispersion])}, "monte_carlo", 50),
        ({"base": base, **member(METHODS)}, "methods", 1),
    ):
        response = client.http.post("/v1/batches", json=body)
        assert response.status_code == 202, response.text
        batch = response.json()
        assert (batch["kind"], batch["size"]) == (kind, size)
        assert client.http.delete(f"/v1/batches/{batch['id']}").status_code in (200, 202)
        assert wait_batch(client, batch["id"], timeout=120)["status"] == "cancelled"


def test_start_from_an_earlier_job(client: ServiceClient) -> None:
    """A neighbouring problem (a lower heat-rate limit) started from an earlier answer, README's
    member in the scenario's merge patch, takes a few iterations instead of tens."""
    first = client.submit({"scenario": "rlv-max-terminal-velocity"})
    assert client.wait_finished(first["id"])["status"] == "succeeded"
    start = json.loads(json.dumps(member(FROM_JOB)).replace("<id>", first["id"]))
    heat = {"path_constraints": {"heat_rate": {"max_W_m2": 1.45e6}}}
    warm = client.submit({"scenario": "rlv-max-terminal-velocity", "overrides": heat | start})
    assert client.wait_finished(warm["id"])["status"] == "succeeded"
    cold = client.submit({"scenario": "rlv-max-terminal-velocity", "overrides": heat})
    assert client.wait_finished(cold["id"])["status"] == "succeeded"
    counts = [
        len(client.http.get(f"/v1/jobs/{job['id']}/history").json()["iterations"])
        for job in (warm, cold)
    ]
    assert counts[0] <= 9 and counts[1] >= 10, counts  # "a few" and "tens"


def request_of(command: str, base_url: str) -> str:
    """``METHOD /path`` of a documented curl command."""
    method = "DELETE" if "-X DELETE" in command else "POST" if "-X POST" in command else "GET"
    address = base_url.removeprefix("http://")
    path = command.split(address, 1)[1].split()[0].strip("'")
    return f"{method} {path}"


def test_api_tour(server: ApiServer, tmp_path: Path) -> None:
    """Each request of the tour, in its order, on one job: the answers its comments state.
    The job has finished when the cancel comes (the event stream ran to its end), so the
    cancel is refused with 409."""
    example = block(CONTRACT, MIN_HEAT_LOAD).text
    (tmp_path / "problem.json").write_text(example, encoding="utf-8")
    text = block(README, TOUR).text
    steps = commands(localize(text, server.base_url))
    submit = curl(steps[0], tmp_path)
    assert submit.status == 202, submit.body
    job_id = submit.json()["id"]
    assert submit.headers["location"] == f"/v1/jobs/{job_id}"
    answers = [
        (request_of(step, server.base_url), curl(step, tmp_path))
        for step in (step.replace("<id>", job_id) for step in steps[1:])
    ]
    job = f"/v1/jobs/{job_id}"
    assert [(request, answer.status) for request, answer in answers] == [
        (f"GET {job}", 200),
        (f"GET {job}/events", 200),
        (f"GET {job}/result", 200),
        (f"GET {job}/history", 200),
        (f"GET {job}/problem", 200),
        (f"DELETE {job}", 409),
        ("GET /v1/jobs?status=succeeded&limit=20", 200),
        ("POST /v1/problems/validate", 200),
        ("GET /v1/scenarios", 200),
        ("GET /v1/methods", 200),
        ("GET /healthz", 200),
        ("GET /readyz", 200),
        ("GET /metrics", 200),
    ]
    (
        polled,
        events,
        result,
        history,
        problem,
        cancel,
        listed,
        validated,
        scenarios,
        methods,
        *health,
    ) = (answer for _, answer in answers)
    assert {"status", "attempts", "progress"} <= set(polled.json())
    progress = {"phase", "iteration", "cost", "max_state_change", "elapsed_s"}
    assert polled.json()["progress"] is None or progress <= set(polled.json()["progress"])
    ended = curl(steps[1].replace("<id>", job_id), tmp_path).json()["progress"]
    assert progress <= set(ended) and ended["phase"] == "finished", ended
    assert "event: iteration" in events.body and "event: end" in events.body
    solved = result.json()
    assert solved["status"] == "succeeded" and history.json()["iterations"]
    canonical = json.dumps(problem.json(), sort_keys=True, separators=(",", ":"))
    assert hashlib.sha256(canonical.encode()).hexdigest() == solved["provenance"]["problem_sha256"]
    assert "409 once it has finished" in text and cancel.json()["error"]["code"]
    assert job_id in {item["id"] for item in listed.json()["items"]}
    assert validated.json()["valid"] is True
    assert "rlv-min-heat-load" in scenarios.body and "energy-scp" in methods.body
    assert "trajopt_" in health[2].body
    assert "409 while the job is not finished" in text
    running = curl(steps[0], tmp_path).json()["id"]
    early = curl(steps[3].replace("<id>", running), tmp_path)  # the result, at once
    assert early.status == 409, early.body


# --- README and the contract: overrides, infeasible problems ---------------------------------


def test_overrides(client: ServiceClient) -> None:
    """README's merge patch on ``rlv-max-terminal-velocity`` succeeds, verified, at the speed it
    states."""
    body = json.loads(block(README, OVERRIDES).text)
    job = client.submit(body)
    done = client.wait_finished(job["id"], timeout=300)
    assert done["status"] == "succeeded", done
    result = client.http.get(f"/v1/jobs/{job['id']}/result").json()
    assert result["verification"]["feasible"] is True
    stated = re.search(r"it succeeds: ([\d.]+) m/s, verified", readme_text())
    assert stated and f"{result['objective']['value']:.2f}" == stated.group(1), result


def readme_text() -> str:
    """README as one line of words (its prose wraps)."""
    return words((REPO_ROOT / README).read_text(encoding="utf-8"))


def test_infeasible_before_any_iteration(client: ServiceClient) -> None:
    """README's switch to US76 (the planet part of its merge patch) on ``rlv-min-heat-load``
    fails at once, code ``infeasible``, with the message and the advice both documents quote."""
    switch = {"planet": json.loads(block(README, OVERRIDES).text)["overrides"]["planet"]}
    assert "The same switch to US76 on `rlv-min-heat-load` fails at once" in readme_text()
    body = {"scenario": "rlv-min-heat-load", "overrides": switch}
    job = client.submit(body)
    done = client.wait_finished(job["id"], timeout=120)
    assert (done["status"], done["error"]["code"]) == ("failed", "infeasible"), done
    result = client.http.get(f"/v1/jobs/{job['id']}/result").json()
    assert result["history"] == []
    message, advice = result["failure"]["message"], result["failure"]["advice"]
    advice_text = advice if isinstance(advice, str) else " ".join(advice)
    quoted = block(CONTRACT, INFEASIBLE[:40]).text
    said, _, advised = quoted.partition("\nadvice: ")
    assert words(message) == words(said)
    assert words(advice_text).startswith(words(advised)), advice_text
    assert words(message) == block(README, INFEASIBLE).text == INFEASIBLE
    assert words(advice_text).startswith(ADVICE.removesuffix(" ..."))


def test_two_phase_example(client: ServiceClient) -> None:
    """The contract's two-phase example is valid and names no method (``auto``); the one method
    that accepts phases and propulsion is lgl-sqp, and naming energy-scp is answered 422
    ``unsupported_by_method`` at ``phases`` and ``vehicle.propulsion``."""
    document = json.loads(block(CONTRACT, TWO_PHASES).text)
    assert "method" not in document
    response = client.http.post("/v1/problems/validate", json=document)
    assert response.status_code == 200, response.text
    assert response.json()["problem"]["method"]["name"] == "auto"
    methods = {m["name"]: m for m in client.http.get("/v1/methods").json() if m["name"] != "auto"}
    assert [name for name, m in methods.items() if m["phases"] and m["propulsion"]] == ["lgl-sqp"]
    assert (methods["energy-scp"]["phases"], methods["energy-scp"]["propulsion"]) == (False, False)
    named = client.http.post(
        "/v1/problems/validate", json={**document, "method": {"name": "energy-scp"}}
    )
    assert named.status_code == 422, named.text
    issues = named.json()["error"]["issues"]
    assert {i["code"] for i in issues} == {"unsupported_by_method"}, issues
    assert {"phases", "vehicle.propulsion"} <= {i["field"] for i in issues}, issues


def test_error_shape(client: ServiceClient) -> None:
    """A document with a negative mass and one node: 422 in the documented shape, its two
    issues as documented."""
    shown = json.loads(block(SERVICE, ERRORS).text)["error"]
    document = json.loads(block(CONTRACT, MIN_HEAT_LOAD).text)
    document["vehicle"]["mass_kg"] = -1
    document["method"]["nodes"] = 1
    response = client.http.post("/v1/problems/validate", json=document)
    assert response.status_code == 422, response.text
    error = response.json()["error"]
    assert (error["code"], error["field"]) == (shown["code"], shown["field"])
    assert error["message"].startswith(shown["message"].removesuffix("..."))
    keys = ("field", "message", "code")
    assert [{k: i[k] for k in keys} for i in error["issues"]] == shown["issues"]


# --- README and the service: Redis, PostgreSQL, workers; keys --------------------------------


def exports(text: str) -> dict[str, str]:
    """The variables the ``export`` lines of a block set, as bash expands them."""
    lines = [line for line in commands(text) if line.startswith("export ")]
    names = [part.split("=")[0] for line in lines for part in line.split()[1:] if "=" in part]
    script = "; ".join(lines) + "; " + "; ".join(f'printf "%s\\n" "${name}"' for name in names)
    run = sh(script, REPO_ROOT)
    assert run.code == 0, run.err
    return dict(zip(names, run.out.splitlines(), strict=True))


def postgres_url() -> str:
    """A PostgreSQL URL of the loopback server that can create schemas."""
    return admin_postgres_url()


class ShellProcess(ServiceProcess):
    """A documented long-running command (a server, a worker) run by bash in a folder."""

    def __init__(self, command: str, env: dict[str, str], log_path: Path, cwd: Path) -> None:
        super().__init__([command], env, log_path)
        self.cwd = cwd

    def start(self) -> None:
        """Start ``bash -c command`` in a new session, its output in the log."""
        self._log = self.log_path.open("a", encoding="utf-8")
        self.process = subprocess.Popen(
            ["bash", "-c", f"exec {self.args[0]}"],
            cwd=self.cwd,
            env=self.env,
            stdout=self._log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )


@pytest.mark.parametrize("document", [README, SERVICE])
def test_redis_postgresql_and_separate_workers(document: str, tmp_path: Path) -> None:
    """The API and a Celery worker on PostgreSQL and Redis, by the documented environment and
    commands (the URLs' hosts made the loopback's, in a schema, a Redis database and a queue of
    this test's own): ready (database and Celery checks), and a job submitted to the API solved
    by the worker."""
    text = block(document, STACK).text
    settings = exports(text)
    admin = postgres_url()
    scheme = settings["DATABASE_URL"].split("://")[0]
    assert scheme in ("postgresql", "postgresql+psycopg"), scheme
    schema = f"trajopt_docs_{uuid.uuid4().hex[:10]}"
    with psycopg.connect(admin, autocommit=True) as conn:
        conn.execute(f'CREATE SCHEMA "{schema}"')
    redis_base = os.environ.get("TEST_REDIS_URL", "redis://127.0.0.1:6379").rstrip("/")
    try:
        redis.Redis.from_url(redis_base, socket_connect_timeout=3).ping()
    except redis.RedisError as exc:
        require("Redis", str(exc))
    env = command_env(
        DATABASE_URL=scheme
        + "://"
        + admin.split("://", 1)[1]
        + f"?options=-csearch_path%3D{schema}",
        REDIS_URL=f"{redis_base}/{uuid.uuid4().int % 15 + 1}",
        TRAJOPT_QUEUE_NAME=f"trajopt-docs-{uuid.uuid4().hex[:10]}",
        TRAJOPT_DATA_DIR=str(tmp_path / "data"),
    )
    assert settings["REDIS_URL"].startswith("redis://")
    serve, worker = (
        line.split("#")[0].strip() for line in commands(text) if line.startswith("trajopt ")
    )
    port = free_port()
    assert "--port 8000" in serve and worker == "trajopt worker --concurrency 2"
    api = ShellProcess(
        serve.replace("--port 8000", f"--port {port}"), env, tmp_path / "api.log", tmp_path
    )
    workers = ShellProcess(worker, env, tmp_path / "worker.log", tmp_path)
    try:
        api.start()
        workers.start()
        workers.wait_for_output(" ready.", timeout=120)
        stack = ServiceClient(f"http://127.0.0.1:{port}")
        try:
            deadline = time.monotonic() + 60
            while True:
                try:
                    ready = stack.http.get("/readyz")
                    if ready.status_code == 200:
                        break
                except httpx.HTTPError:
                    pass
                assert time.monotonic() < deadline and api.alive(), api.log_text()[-3000:]
                time.sleep(0.3)
            assert ready.json()["checks"] == {"database": "ok", "celery": "ok"}, ready.json()
            job = stack.submit({"scenario": "rlv-min-heat-load", "method": {"nodes": 41}})
            assert stack.wait_finished(job["id"], timeout=180)["status"] == "succeeded"
        finally:
            stack.close()
    finally:
        workers.stop()
        api.stop()
        forget_queue(env["REDIS_URL"], env["TRAJOPT_QUEUE_NAME"])
        with psycopg.connect(admin, autocommit=True) as conn:
            conn.execute(f'DROP SCHEMA IF EXISTS "{schema}" CASCADE')


def test_keys(tmp_path: Path) -> None:
    """In api-keys mode: a key created for ``flight-dynamics`` (printed once) lets curl list
    that client's jobs; ``keys list`` shows it; once ``keys revoke KEY_ID`` has run, the same
    request is refused."""
    text = block(README, KEYS).text
    settings = exports(text)
    assert settings["TRAJOPT_AUTH_MODE"] == "api-keys"
    assert re.fullmatch(r"[0-9a-f]{64}", settings["TRAJOPT_API_KEY_SECRET"])
    env = command_env(TRAJOPT_DATA_DIR=str(tmp_path / "data"), **settings)
    create, listing, revoke, request = commands(text)[1:]
    run = sh(create.split("#")[0], tmp_path, env)
    assert run.code == 0, run.err
    key = run.out.strip()
    assert len(run.out.splitlines()) == 1 and key, run.out
    api = ApiServer(env, tmp_path / "api.log")
    api.start_and_wait()
    try:
        env["KEY"] = key
        request = localize(request, api.base_url)
        answer = curl(request, tmp_path, env)
        assert answer.status == 200 and answer.json()["items"] == [], answer.body
        run = sh(listing, tmp_path, env)
        assert run.code == 0, run.err
        row = next(line for line in run.out.splitlines() if "flight-dynamics" in line)
        key_id = row.split()[0]
        run = sh(revoke.replace("KEY_ID", key_id), tmp_path, env)
        assert run.code == 0, run.err
        refused = curl(request, tmp_path, env)
        assert refused.status == 401, refused.body
    finally:
        api.stop()
