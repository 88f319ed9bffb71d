"""Property-based fuzzing of the HTTP API from its own OpenAPI document (schemathesis).

Every operation gets generated requests, valid and invalid, plus stateful chains that follow
the ``Location`` of a submission to the job's routes (show, result, history, cancel). The
checks: no 5xx, status codes, content types, headers and bodies as documented. The app runs
in-process in api-keys mode; submitted jobs run at once through the real ``execute_job`` with a
scripted solve (every other one is left queued), so chains meet queued and finished jobs.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

schemathesis = pytest.importorskip("schemathesis")

from fastapi.testclient import TestClient  # noqa: E402
from hypothesis import HealthCheck, settings  # noqa: E402
from schemathesis import checks as st_checks  # noqa: E402

from app.auth import create_key  # noqa: E402
from app.main import create_app  # noqa: E402
from app.settings import Settings  # noqa: E402
from app.storage.session import get_database  # noqa: E402
from tests.unit.test_service_api import RecordingDispatcher  # noqa: E402
from tests.unit.test_service_execute_job import scripted  # noqa: E402
from worker.jobs import execute_job  # noqa: E402
from worker.limits import TimeLimits  # noqa: E402
from worker.solver.result import validated  # noqa: E402

pytestmark = pytest.mark.slow

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

    def submit(self, job_id: str, limits: TimeLimits) -> None:
        super().submit(job_id, limits)
        if len(self.submitted) % 2:
            execute_job(job_id, settings=self.settings, solve=contract_solve)


def contract_solve(problem: Any, *, on_iteration: Any, should_stop: Any) -> dict[str, Any]:
    """:func:`scripted`'s solve, its result made a valid ``ResultDocument`` (it is documented)."""
    result = scripted(2)(problem, on_iteration=on_iteration, should_stop=should_stop)
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
            max_active_jobs=10_000,
            event_ping_interval_s=0.05,
        )
        self.app = create_app(self.settings, InstantDispatcher(self.settings))
        self.client = TestClient(self.app)
        self.client.__enter__()  # runs the lifespan: database, sweeper, dispatcher
        _, key = create_key(get_database(self.settings.effective_database_url), self.settings, "fz")
        self.headers = {"X-API-Key": key}


@pytest.fixture(scope="module")
def running(tmp_path_factory: pytest.TempPathFactory) -> Iterator[App]:
    app = App(tmp_path_factory.mktemp("fuzz"))
    yield app
    app.client.__exit__(None, None, None)


def _schema(app: App) -> Any:
    schema = schemathesis.openapi.from_asgi("/openapi.json", app.app)
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
