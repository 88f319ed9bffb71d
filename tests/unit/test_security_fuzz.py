"""Property-based fuzzing of the HTTP API from its own OpenAPI document (schemathesis).

Every operation gets generated requests, valid and invalid, plus stateful chains that follow
the ``Location`` of a submission to the job's routes (show, result, history, cancel). The
checks: no 5xx, status codes, content types, headers and bodies as documented. The app runs
in-process in api-keys mode; submitted jobs run at once through the real ``execute_job`` with a
scripted solve (every other one is left queued), so chains meet queued and finished jobs.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

schemathesis = pytest.importorskip("schemathesis")

from fastapi.testclient import TestClient  # noqa: E402
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from schemathesis import checks as st_checks  # noqa: E402
from schemathesis.config import OperationConfig  # noqa: E402
from sqlalchemy import delete  # noqa: E402

from app.auth import create_key  # noqa: E402
from app.main import create_app  # noqa: E402
from app.settings import Settings  # noqa: E402
from app.storage.models import Batch, Job  # noqa: E402
from app.storage.session import get_database  # noqa: E402
from tests.unit.test_service_api import RecordingDispatcher  # noqa: E402
from tests.unit.test_service_execute_job import scripted  # noqa: E402
from worker.jobs import execute_job  # noqa: E402
from worker.limits import TimeLimits  # noqa: E402
from worker.solver.result import validated  # noqa: E402

pytestmark = pytest.mark.slow

SCENARIO = "rlv-min-heat-load"

MAX_EXAMPLES = 40
"""Generated requests per operation: bounds the run to about a minute on two cores."""
STATEFUL_EXAMPLES = 40
CHECKS = [
    st_checks.not_a_server_error,
    st_checks.status_code_conformance,
    st_checks.content_type_conformance,
    st_checks.response_headers_conformance,
    st_checks.response_schema_conformance,
]


class InstantDispatcher(RecordingDispatcher):
    """Runs every other job to completion right away, through the real execution path."""

    def __init__(self, settings: Settings) -> None:
        super().__init__()
        self.settings = settings

    def submit(self, job_id: str, limits: TimeLimits, priority: int = 0) -> None:
        super().submit(job_id, limits, priority)
        if len(self.submitted) % 2:
            execute_job(job_id, settings=self.settings, solve=contract_solve)


def contract_solve(
    problem: Any, *, on_iteration: Any, should_stop: Any, on_phase: Any = None
) -> dict[str, Any]:
    """:func:`scripted`'s solve, its result made a valid ``ResultDocument`` (it is documented)."""
    result = scripted(2)(
        problem, on_iteration=on_iteration, should_stop=should_stop, on_phase=on_phase
    )
    name = str(problem.method.name)
    objective = {"name": "min_heat_load", "value": result.pop("objective", None), "units": "J/m^2"}
    return validated({**result, "method": name, "objective": objective})


class App:
    """The application under test and the key its requests carry."""

    def __init__(self, tmp: Path) -> None:
        self.settings = Settings(
            data_dir=tmp,
            database_url="",
            broker_url="",
            auth_mode="api-keys",
            api_key_secret="fuzz-only-0123456789abcdef0123456789",
            rate_read_per_window=0,
            rate_submit_per_window=0,
            rate_auth_failures_per_window=0,  # hostile keys are the point: no lockout
            max_active_jobs=10_000,
            event_ping_interval_s=0.05,
        )
        self.dispatcher = InstantDispatcher(self.settings)
        self.app = create_app(self.settings, self.dispatcher)
        self.client = TestClient(self.app)
        self.client.__enter__()  # runs the lifespan: database, sweeper, dispatcher
        _, key = create_key(get_database(self.settings.effective_database_url), self.settings, "fz")
        self.headers = {"X-API-Key": key}

    def forget_jobs(self) -> None:
        """Delete every job and batch and restart the dispatcher's alternation."""
        database = get_database(self.settings.effective_database_url)
        with database.session() as session:
            session.execute(delete(Job))
            session.execute(delete(Batch))
        self.dispatcher.submitted.clear()
        self.dispatcher.priorities.clear()


@pytest.fixture(scope="module")
def running(tmp_path_factory: pytest.TempPathFactory) -> Iterator[App]:
    app = App(tmp_path_factory.mktemp("fuzz"))
    yield app
    app.client.__exit__(None, None, None)


NO_BOUNDARY_CASES = OperationConfig.from_dict(
    {"include-name": "POST /v1/jobs", "phases": {"coverage": {"enabled": False}}}
)
"""The coverage phase sends every boundary case of a request body's schema (thousands for a
problem document). POST /v1/problems/validate and POST /v1/jobs take the same body through the
same validation, so the boundary cases run once, against validate; job submission keeps its
generated and stateful cases (what it adds to validation: storage and dispatch)."""


def _schema(app: App) -> Any:
    schema = schemathesis.openapi.from_asgi("/openapi.json", app.app)
    schema.config.operations.operations.append(NO_BOUNDARY_CASES)
    # An event stream of a queued job stays open until the job ends, which a fuzzer cannot
    # wait for; the streams are tested in test_service_api. /metrics is plain text.
    return schema.exclude(path_regex=r".*/events$").exclude(path="/metrics")


@pytest.fixture(scope="module")
def api_schema(running: App) -> Any:
    return _schema(running)


lazy_schema = schemathesis.pytest.from_fixture("api_schema")


@lazy_schema.parametrize()
@settings(
    max_examples=MAX_EXAMPLES,
    deadline=None,
    suppress_health_check=list(HealthCheck),
    derandomize=True,
    database=None,
)
def test_every_operation_answers_as_documented(case: Any, running: App) -> None:
    case.call_and_validate(headers=running.headers, checks=CHECKS)


def test_submit_then_poll_chains(running: App) -> None:
    schema = _schema(running)
    machine = schema.as_state_machine()

    class Chains(machine):  # type: ignore[misc, valid-type]
        def setup(self) -> None:
            """Each scenario from an empty job store and the dispatcher's alternation at its
            start: what a scenario's rules may chain to then depends on the scenario alone, as
            Hypothesis needs to replay and shrink it (left over jobs of earlier scenarios would
            change the lists and statuses the links draw from)."""
            running.forget_jobs()

        def get_call_kwargs(self, case: Any) -> dict[str, Any]:
            return {"headers": running.headers}

        def validate_response(self, response: Any, case: Any, **kwargs: Any) -> None:
            case.validate_response(response, checks=CHECKS)

    Chains.TestCase.settings = settings(
        max_examples=STATEFUL_EXAMPLES,
        stateful_step_count=8,
        deadline=None,
        suppress_health_check=list(HealthCheck),
        derandomize=True,
        database=None,
    )
    Chains.TestCase().runTest()


# --- hostile input classes the OpenAPI document does not describe -----------------------------

_TEXT = st.text(alphabet=st.characters(codec=None, categories=None), max_size=12)
"""Any code points, NUL and lone surrogates included."""


def _hostile_body(draw: Any) -> tuple[str, dict[str, str], bool]:
    """A JSON body (as text) of one class, the headers to send it with, and whether it is
    hostile (text without NUL or surrogates is an ordinary string)."""
    kind = draw(st.sampled_from(["text", "nan", "deep", "wide"]))
    headers = {"Content-Type": "application/json"}
    if kind == "text":
        where = draw(st.sampled_from(["name", "description", "key", "scenario"]))
        value = draw(_TEXT)
        if where == "key":
            body: Any = {"scenario": SCENARIO, "overrides": {value: 1}}
        elif where == "scenario":
            body = {"scenario": value}
        else:
            body = {"scenario": SCENARIO, "overrides": {where: value}}
        hostile = where == "scenario" or any(
            c == "\x00" or "\ud800" <= c <= "\udfff" for c in value
        )
        return json.dumps(body), headers, hostile
    if kind == "nan":
        token = draw(st.sampled_from(["NaN", "Infinity", "-Infinity", "1e999", "-1e400"]))
        field = draw(st.sampled_from(["mass_kg", "reference_area_m2"]))
        headers["Idempotency-Key"] = f"fuzz-{draw(st.integers(0, 10**9))}"
        overrides = f'{{"vehicle": {{"{field}": {token}}}}}'
        return f'{{"scenario": "{SCENARIO}", "overrides": {overrides}}}', headers, True
    if kind == "wide":
        nested = "[" + ",".join(["1"] * draw(st.integers(500, 200_000))) + "]"
    else:
        depth = draw(st.integers(10, 10_000))
        opener, closer = draw(st.sampled_from([("[", "]"), ('{"a": ', "}")]))
        nested = opener * depth + "1" + closer * depth
    where = draw(st.sampled_from(["overrides", "method"]))
    return f'{{"scenario": "{SCENARIO}", "{where}": {{"x": {nested}}}}}', headers, True


@settings(
    max_examples=MAX_EXAMPLES,
    deadline=None,
    suppress_health_check=list(HealthCheck),
    derandomize=True,
    database=None,
)
@given(data=st.data())
def test_hostile_bodies_and_job_ids_are_4xx_naming_the_field(running: App, data: Any) -> None:
    """NUL and lone surrogates anywhere, non-finite numbers with an Idempotency-Key, nesting 10
    to 10 000 levels deep, huge arrays, and job ids with NUL or bad UTF-8: each a 4xx in the
    common error shape, a 422 naming its field."""
    text, headers, hostile = _hostile_body(data.draw)
    path = data.draw(st.sampled_from(["/v1/jobs", "/v1/problems/validate"]))
    response = running.client.post(
        path, content=text.encode("utf-8", "surrogatepass"), headers={**running.headers, **headers}
    )
    if not hostile:  # ordinary text: stored and answered like any other
        assert response.status_code in (200, 202, 422), response.text[:300]
        return
    assert 400 <= response.status_code < 500, (text[:200], response.text[:300])
    error = response.json()["error"]
    if response.status_code == 422:
        assert error["field"] is not None and error["issues"], error
    ident = data.draw(st.sampled_from(["%00", "a%00", "%ED%A0%80", "%FF", "x" * 3000]))
    suffix = data.draw(st.sampled_from(["", "/result", "/history", "/events"]))
    response = running.client.get(f"/v1/jobs/{ident}{suffix}", headers=running.headers)
    assert response.status_code == 404, response.text[:300]
    assert response.json()["error"]["code"] == "job_not_found"
