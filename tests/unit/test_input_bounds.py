"""Hostile and absurd input through the real application: every answer a 4xx naming the field.

Authentication before the body, the structural bounds of a body (depth, array and object sizes,
NUL and surrogates), the cap on the issues of a 422, ``NaN`` with an Idempotency-Key, job ids
that cannot exist, the physical bounds of the contract, and the CPU one invalid megabyte costs.
The application runs in-process in api-keys mode on a SQLite file (the PostgreSQL side of NUL
is in tests/integration/test_hostile_input.py).
"""

from __future__ import annotations

import copy
import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.auth import create_key
from app.body import (
    MAX_ARRAY_ITEMS,
    MAX_CONTAINERS,
    MAX_DEPTH,
    MAX_OBJECT_MEMBERS,
    _deep_location,
    decode_body,
    structure_issue,
)
from app.errors import MAX_ISSUES, ApiError
from app.main import create_app
from app.schemas import RLV_MIN_HEAT_LOAD, ProblemDocument
from app.settings import Settings
from app.storage.session import get_database
from app.submission import request_fingerprint
from tests.unit.test_service_api import RecordingDispatcher

SECRET = "0123456789abcdef0123456789abcdef-bounds-only"
JSON = {"Content-Type": "application/json"}
SCENARIO = "rlv-min-heat-load"
ROUTES = ("/v1/jobs", "/v1/problems/validate")


class Api:
    """The application in api-keys mode, a test client, and one client's headers."""

    def __init__(self, tmp: Path) -> None:
        self.settings = Settings(
            data_dir=tmp,
            database_url="",
            broker_url="",
            auth_mode="api-keys",
            api_key_secret=SECRET,
            rate_read_per_window=0,
            rate_submit_per_window=0,
        )
        self.dispatcher = RecordingDispatcher()
        self.http = TestClient(create_app(self.settings, self.dispatcher))
        self.http.__enter__()
        database = get_database(self.settings.effective_database_url)
        self.headers = {"X-API-Key": create_key(database, self.settings, "bounds")[1], **JSON}

    def post(self, path: str, body: bytes | str | Any, **headers: str) -> Any:
        """POST ``body`` (raw JSON text, or a value to encode) with the client's key."""
        content = body if isinstance(body, bytes | str) else json.dumps(body)
        return self.http.post(path, content=content, headers={**self.headers, **headers})


@pytest.fixture
def api(tmp_path: Path) -> Iterator[Api]:
    app = Api(tmp_path)
    yield app
    app.http.__exit__(None, None, None)


def _doc(**changes: Any) -> dict[str, Any]:
    """The reference problem with ``changes`` merged in at dotted paths."""
    document = copy.deepcopy(RLV_MIN_HEAT_LOAD)
    for path, value in changes.items():
        *parents, last = path.split("__")
        target = document
        for name in parents:
            target = target[name]
        target[last] = value
    return document


def _error(response: Any, status: int = 422) -> dict[str, Any]:
    assert response.status_code == status, response.text
    error: dict[str, Any] = response.json()["error"]
    return error


def _nested(depth: int, opener: str = "[", closer: str = "]") -> str:
    return opener * depth + "1" + closer * depth


# --- authentication comes before the body ------------------------------------------------------


@pytest.mark.parametrize("path", ROUTES)
@pytest.mark.parametrize(
    "body",
    [b'{"scenario": ', b"\xff\xfe", b"", b"[1, 2]", f'{{"x": {_nested(5000)}}}'.encode()],
    ids=["cut-off", "not-utf8", "empty", "not-an-object", "too-deep"],
)
def test_a_body_without_a_key_is_401_whatever_it_holds(api: Api, path: str, body: bytes) -> None:
    response = api.http.post(path, content=body, headers=JSON)
    assert _error(response, 401)["code"] == "missing_api_key"
    response = api.http.post(path, content=body, headers={**JSON, "X-API-Key": "tj_wrong"})
    assert _error(response, 401)["code"] == "invalid_api_key"


@pytest.mark.parametrize("path", ROUTES)
def test_with_a_key_the_same_bodies_are_refused_for_what_they_are(api: Api, path: str) -> None:
    assert _error(api.post(path, b'{"scenario": '), 400)["code"] == "malformed_body"
    assert _error(api.post(path, b"[1, 2]"))["code"] == "invalid_request"
    response = api.http.post(path, content=b"{}", headers={"X-API-Key": api.headers["X-API-Key"]})
    assert _error(response, 415)["field"] == "Content-Type"


# --- structural bounds -------------------------------------------------------------------------


@pytest.mark.parametrize("path", ROUTES)
@pytest.mark.parametrize("depth", [MAX_DEPTH + 1, 500, 999, 1000, 10_000, 100_000])
@pytest.mark.parametrize("where", ["overrides", "method"])
def test_deep_nesting_is_422_naming_where_it_goes_too_deep(
    api: Api, path: str, depth: int, where: str
) -> None:
    body = f'{{"scenario": "{SCENARIO}", "{where}": {{"a": {_nested(depth)}}}}}'
    error = _error(api.post(path, body))
    assert error["code"] == "invalid_request"
    assert error["field"] == f"{where}.a" + "[0]" * (MAX_DEPTH - 2)
    assert error["issues"][0]["code"] == "too_deep"
    assert f"more than {MAX_DEPTH} levels deep" in error["message"]


@pytest.mark.parametrize("depth", [10, MAX_DEPTH - 3])
def test_nesting_within_the_bound_reaches_validation(api: Api, depth: int) -> None:
    body = f'{{"scenario": "{SCENARIO}", "overrides": {{"method": {{"x": {_nested(depth)}}}}}}}'
    error = _error(api.post("/v1/problems/validate", body))
    assert (error["code"], error["field"]) == ("invalid_problem", "method.x")


@pytest.mark.parametrize(
    ("body", "field", "code"),
    [
        (
            {"scenario": SCENARIO, "overrides": {"no_fly_zones": [{}] * 100_000}},
            "overrides.no_fly_zones",
            "too_many_items",
        ),
        (
            {**RLV_MIN_HEAT_LOAD, **{f"x{i}": 0 for i in range(MAX_OBJECT_MEMBERS)}},
            "",
            "too_many_members",
        ),
        (
            {"scenario": SCENARIO, "overrides": {f"k{i}": [[]] * 1000 for i in range(9)}},
            "overrides.k4[993]",
            "too_many_containers",
        ),
        (_doc(name="zone\x00"), "name", "nul_character"),
        (_doc(no_fly_zones=[{"name": "a\x00b"}]), "no_fly_zones[0].name", "nul_character"),
        (
            {"scenario": SCENARIO, "overrides": {"na\x00me": 1}},
            "overrides.na\x00me",
            "nul_character",
        ),
        ({"scenario": "\ud800"}, "scenario", "invalid_text"),
    ],
    ids=["items", "members", "containers", "nul", "nul-in-a-list", "nul-in-a-key", "surrogate"],
)
@pytest.mark.parametrize("path", ROUTES)
def test_structural_bounds_are_422_naming_the_field(
    api: Api, path: str, body: Any, field: str, code: str
) -> None:
    error = _error(api.post(path, body))
    assert (error["code"], error["field"], error["issues"][0]["code"]) == (
        "invalid_request",
        field,
        code,
    )
    assert error["issues_total"] == 1
    assert api.dispatcher.submitted == []


def test_a_raw_surrogate_in_utf8_is_refused_too(api: Api) -> None:
    body = b'{"scenario": "\xed\xa0\x80"}'  # UTF-8 of U+D800, which json.loads lets through
    assert _error(api.post("/v1/jobs", body))["issues"][0]["code"] == "invalid_text"


def test_structure_issue_and_deep_location_agree() -> None:
    text = '{"a": [1, {"b": "x", "c": ' + _nested(40) + "}]}"
    decoded = structure_issue(json.loads(text))
    assert decoded is not None
    assert _deep_location(text) == ("a", 1, "c", *([0] * (MAX_DEPTH - 3)))
    assert decoded.field == "a[1].c" + "[0]" * (MAX_DEPTH - 3)
    escaped = '{"q\\"uo,te": [0, 0, ' + _nested(40, '{"k": ', "}").replace("1", "2") + "]}"
    assert _deep_location(escaped)[:3] == ('q"uo,te', 2, "k")
    assert structure_issue(json.loads(escaped)) == structure_issue(json.loads(escaped), True)


def test_the_bounds_leave_room_for_every_real_document() -> None:
    assert structure_issue(RLV_MIN_HEAT_LOAD) is None
    table = {
        "model": "table",
        "alpha_deg": list(range(-50, 150)),
        "mach": list(range(200)),
        "cl": [[0.1] * 200] * 200,
        "cd": [[0.1] * 200] * 200,
    }
    big = _doc(vehicle__aerodynamics=table)
    assert structure_issue({"scenario": SCENARIO, "overrides": big}) is None
    assert MAX_ARRAY_ITEMS >= 200 and MAX_CONTAINERS >= 2 * 200 + 100


# --- the issues of a 422 are capped -----------------------------------------------------------


@pytest.mark.parametrize("path", ROUTES)
def test_a_422_lists_the_first_issues_and_counts_them_all(api: Api, path: str) -> None:
    many = {f"unknown_{i:02d}": 1 for i in range(80)}
    error = _error(api.post(path, {**RLV_MIN_HEAT_LOAD, **many}))
    assert error["code"] == "invalid_problem"
    assert len(error["issues"]) == MAX_ISSUES
    assert error["issues_total"] == 80
    assert error["message"].startswith("the problem has 80 error(s); first: unknown_00:")
    assert f"issues lists the first {MAX_ISSUES}" in error["message"]
    few = _error(api.post(path, {**RLV_MIN_HEAT_LOAD, "unknown": 1}))
    assert (len(few["issues"]), few["issues_total"]) == (1, 1)
    assert "lists the first" not in few["message"]


def test_query_validation_is_capped_too(api: Api) -> None:
    query = "&".join(["status=nope"] * 120)
    error = _error(api.http.get(f"/v1/jobs?{query}", headers=api.headers))
    assert (len(error["issues"]), error["issues_total"]) == (MAX_ISSUES, 120)


@pytest.mark.slow
@pytest.mark.parametrize("path", ROUTES)
def test_one_invalid_megabyte_costs_little_cpu(api: Api, path: str) -> None:
    """Each body below fills the 1 MB limit with invalid items; before the bounds, such bodies
    took 1.5 to 6 s of CPU and answered up to 37 MB. The bound allows 0.5 s per body: 6 to
    40 times the measured cost, for a shared two-core machine. The process's CPU clock also
    counts other threads (a collection, a previous test's helper), so each body is timed three
    times and the least is compared: a regression costs every try, a stray thread one."""
    limit = api.settings.max_body_bytes
    aoa = {"mode": "table", "velocity_m_s": [0, 1], "alpha_deg": ["x"] * (limit // 5)}
    rows = {"model": "table", "alpha_deg": [0, 1], "mach": [0, 1], "cd": [[1, 1]] * 2}
    bodies = [
        _doc(vehicle__angle_of_attack=aoa),
        _doc(vehicle__aerodynamics={**rows, "cl": [["x"] * 200] * 200}),
        {**RLV_MIN_HEAT_LOAD, **{f"u{i}": ["x"] * 900 for i in range(80)}},
        {"scenario": SCENARIO, "overrides": {f"k{i}": [{}] * 1000 for i in range(90)}},
    ]
    for body in bodies:
        raw = json.dumps(body, separators=(",", ":")).encode()
        assert len(raw) <= limit
        tries = []
        for _ in range(3):
            started = time.process_time()
            response = api.post(path, raw)
            tries.append(time.process_time() - started)
            assert response.status_code == 422, response.text[:300]
            assert len(response.content) < 20_000
        assert min(tries) < 0.5, (tries, response.json()["error"]["message"])


# --- NaN with an Idempotency-Key, job ids that cannot exist ------------------------------------


@pytest.mark.parametrize("token", ["NaN", "Infinity", "-Infinity", "1e999"])
def test_a_non_finite_number_with_an_idempotency_key_is_422_naming_it(api: Api, token: str) -> None:
    text = json.dumps(_doc(vehicle__mass_kg=12345.0)).replace("12345.0", token)
    error = _error(api.post("/v1/jobs", text, **{"Idempotency-Key": f"nan-{token}"}))
    assert (error["field"], error["issues"][0]["code"]) == ("vehicle.mass_kg", "finite_number")
    body = {"scenario": SCENARIO, "overrides": {"vehicle": {"mass_kg": 1}}}
    overrides = json.dumps(body).replace(": 1}", f": {token}}}")
    error = _error(api.post("/v1/jobs", overrides, **{"Idempotency-Key": f"nan-o-{token}"}))
    assert error["field"] == "vehicle.mass_kg"
    assert request_fingerprint({"x": float("nan")}) == request_fingerprint({"x": float("nan")})


@pytest.mark.parametrize(
    "job_id", ["%00", "abc%00def", "x" * 5000, "%ED%A0%80", "3F2B8C1E-6D0A-4C55-9D1E-2A7F3B9C4E10"]
)
def test_a_job_id_that_cannot_exist_is_the_404_of_an_unknown_job(api: Api, job_id: str) -> None:
    unknown = "3f2b8c1e-6d0a-4c55-9d1e-2a7f3b9c4e10"
    for suffix, method in (("", "GET"), ("/result", "GET"), ("/history", "GET"), ("", "DELETE")):
        for ident in (job_id, unknown):
            response = api.http.request(method, f"/v1/jobs/{ident}{suffix}", headers=api.headers)
            error = _error(response, 404)
            assert error["code"] == "job_not_found"
            assert error["message"].startswith("no job ")
    response = api.http.get(f"/v1/jobs/{job_id}", headers={"X-API-Key": "tj_wrong"})
    assert _error(response, 401)["code"] == "invalid_api_key"  # the key is checked first


# --- physical bounds of the contract -----------------------------------------------------------


@pytest.mark.parametrize(
    ("changes", "field", "code"),
    [
        ({"vehicle__mass_kg": 1e308}, "vehicle.mass_kg", "less_than_equal"),
        ({"vehicle__mass_kg": 1e-9}, "vehicle.mass_kg", "below_minimum"),
        ({"vehicle__reference_area_m2": 1e-300}, "vehicle.reference_area_m2", "below_minimum"),
        ({"vehicle__reference_area_m2": 1e300}, "vehicle.reference_area_m2", "less_than_equal"),
        ({"initial_state__velocity_m_s": 1e9}, "initial_state.velocity_m_s", "less_than_equal"),
        ({"initial_state__altitude_m": -10.0}, "initial_state.altitude_m", "greater_than"),
        ({"initial_state__altitude_m": 1e12}, "initial_state.altitude_m", "less_than_equal"),
        ({"initial_state__time_s": 1e300}, "initial_state.time_s", "less_than_equal"),
        ({"planet__radius_m": 1.0}, "planet.radius_m", "below_minimum"),
        ({"planet__g0_m_s2": 1e6}, "planet.g0_m_s2", "less_than_equal"),
        ({"planet__rotation_rate_rad_s": 10.0}, "planet.rotation_rate_rad_s", "less_than_equal"),
        (
            {"terminal__altitude_m": {"kind": "range", "lo": -5.0, "hi": 1000.0}},
            "terminal.altitude_m.lo",
            "terminal_out_of_domain",
        ),
        (
            {"terminal__velocity_m_s": {"kind": "range", "lo": 0.0, "hi": 1e200}},
            "terminal.velocity_m_s.hi",
            "terminal_out_of_domain",
        ),
        (
            {"method": {"name": "energy-scp", "weight_trust_region": 1e300}},
            "method.weight_trust_region",
            "magnitude_limit",
        ),
    ],
)
@pytest.mark.parametrize("path", ROUTES)
def test_absurd_physical_values_are_422_naming_the_field(
    api: Api, path: str, changes: dict[str, Any], field: str, code: str
) -> None:
    error = _error(api.post(path, _doc(**changes)))
    assert error["code"] == "invalid_problem"
    assert (error["field"], error["issues"][0]["code"]) == (field, code), error


def test_a_planet_given_by_mu_must_have_a_physical_surface_gravity() -> None:
    planet = {"radius_m": 6.4e6, "mu_m3_s2": 1.0, "atmosphere": {"model": "us76"}}
    with pytest.raises(ValueError, match=r"mu / R0\^2 = .* is outside"):
        ProblemDocument.model_validate(_doc(planet=planet))
    ProblemDocument.model_validate(_doc(planet={**planet, "mu_m3_s2": 3.986e14}))


def test_decode_body_refuses_what_fastapi_refused() -> None:
    with pytest.raises(ApiError) as cut:
        decode_body(b'{"a": ', "application/json")
    assert cut.value.status == 400
    with pytest.raises(ApiError) as label:
        decode_body(b"{}", "text/plain")
    assert label.value.status == 415
    assert decode_body(b'{"a": 1}', "application/problem+json; charset=utf-8") == {"a": 1}
