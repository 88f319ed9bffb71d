"""Turning request bodies into validated problems: scenarios, overrides, all errors at once."""

from __future__ import annotations

from typing import Any

import pytest

from app.errors import ApiError
from app.submission import deep_merge, request_fingerprint, resolve_submission
from worker.solver.scenarios import get_scenario

SCENARIO = "rlv-min-heat-load"


def _scenario_name() -> str:
    return get_scenario(SCENARIO).name


def test_deep_merge_merges_objects_and_replaces_the_rest() -> None:
    base = {"a": {"b": 1, "c": [1, 2]}, "d": 1}
    merged = deep_merge(base, {"a": {"c": [3]}, "e": {"f": 1}})
    assert merged == {"a": {"b": 1, "c": [3]}, "d": 1, "e": {"f": 1}}
    assert base == {"a": {"b": 1, "c": [1, 2]}, "d": 1}


def test_fingerprint_ignores_key_order_but_not_values() -> None:
    assert request_fingerprint({"a": 1, "b": [1, 2]}) == request_fingerprint({"b": [1, 2], "a": 1})
    assert request_fingerprint({"a": 1}) != request_fingerprint({"a": 2})


def test_scenario_with_overrides_and_method() -> None:
    name = _scenario_name()
    body = {
        "scenario": name,
        "overrides": {"method": {"nodes": 21}},
        "method": {"max_iterations": 4},
    }
    submission = resolve_submission(body)
    assert submission.scenario == name
    assert submission.document["method"]["nodes"] == 21
    assert submission.document["method"]["max_iterations"] == 4
    assert submission.method == submission.document["method"]["name"]


def test_full_document_is_normalized() -> None:
    problem = get_scenario(_scenario_name()).problem
    submission = resolve_submission(problem)
    assert submission.scenario is None
    assert "schema_version" in submission.document  # defaults are filled in


def _issues(body: Any) -> tuple[ApiError, list[str]]:
    with pytest.raises(ApiError) as caught:
        resolve_submission(body)
    error = caught.value
    assert error.status == 422
    return error, [issue["field"] for issue in error.issues or []]


def test_every_invalid_field_is_reported() -> None:
    overrides = {"method": {"nodes": 1}, "vehicle": {"mass_kg": -5}, "bogus": 1}
    error, fields = _issues({"scenario": _scenario_name(), "overrides": overrides})
    assert error.code == "invalid_problem"
    assert {"method.nodes", "vehicle.mass_kg", "bogus"} <= set(fields)
    assert error.field == fields[0]


def test_unknown_scenario_and_bad_request_shape() -> None:
    error, fields = _issues({"scenario": "no-such-scenario"})
    assert (error.code, fields) == ("invalid_request", ["scenario"])
    error, fields = _issues({"scenario": _scenario_name(), "overrides": [], "extra": 1})
    assert error.code == "invalid_request"
    assert set(fields) == {"overrides", "extra"}
    error, _ = _issues([1, 2])
    assert error.code == "invalid_request"
