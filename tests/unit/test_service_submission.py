"""Turning request bodies into validated problems: scenarios, overrides, all errors at once."""

from __future__ import annotations

from typing import Any

import pytest

from app.errors import ApiError
from app.schemas import EnergyScpOptions, ProblemDocument
from app.submission import apply_overrides, merge_patch, request_fingerprint, resolve_submission
from worker.solver.scenarios import get_scenario

SCENARIO = "rlv-min-heat-load"
NFZ_SCENARIO = "rlv-max-terminal-velocity-nfz"
US76 = {"planet": {"atmosphere": {"model": "us76"}}}


def _scenario_name() -> str:
    return get_scenario(SCENARIO).name


def test_merge_patch_merges_objects_and_replaces_the_rest() -> None:
    base = {"a": {"b": 1, "c": [1, 2]}, "d": 1}
    merged = merge_patch(base, {"a": {"c": [3]}, "e": {"f": 1}, "d": None})
    assert merged == {"a": {"b": 1, "c": [3]}, "e": {"f": 1}}
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


def _resolved(overrides: dict[str, Any], scenario: str = SCENARIO, **extra: Any) -> dict[str, Any]:
    """The normalized problem of a scenario submitted with ``overrides``."""
    body = {"scenario": get_scenario(scenario).name, "overrides": overrides, **extra}
    document: dict[str, Any] = resolve_submission(body).document
    return document


def test_switching_the_atmosphere_to_us76_and_back() -> None:
    assert get_scenario(SCENARIO).problem["planet"]["atmosphere"]["model"] == "exponential"
    document = _resolved(US76)
    assert document["planet"]["atmosphere"] == {"model": "us76"}
    assert document["planet"]["radius_m"] == get_scenario(SCENARIO).problem["planet"]["radius_m"]
    back = apply_overrides(
        document, {"planet": {"atmosphere": {"model": "exponential", "scale_height_m": 7000}}}
    )
    assert back["planet"]["atmosphere"] == {"model": "exponential", "scale_height_m": 7000}
    assert ProblemDocument.model_validate(back).planet.atmosphere.model == "exponential"


def test_same_model_merges_into_the_scenario_s_fields() -> None:
    atmosphere = {"model": "exponential", "scale_height_m": 7000}
    document = _resolved({"planet": {"atmosphere": atmosphere}})
    assert document["planet"]["atmosphere"]["scale_height_m"] == 7000
    scenario_atmosphere = get_scenario(SCENARIO).problem["planet"]["atmosphere"]
    assert (
        document["planet"]["atmosphere"]["density_sea_level_kg_m3"]
        == scenario_atmosphere["density_sea_level_kg_m3"]
    )
    terminal = _resolved({"terminal": {"longitude_deg": {"kind": "soft", "value": 16}}})
    assert terminal["terminal"]["longitude_deg"] == {"kind": "soft", "value": 16, "weight": 200}


def test_switching_the_aerodynamic_model_and_terminal_and_final_time_kinds() -> None:
    polar = {"model": "parabolic_polar", "cl_star": 0.6, "cd0": 0.05, "k_induced": 1.2}
    # a polar has no angle of attack: the override removes the scenario's law (merge-patch null)
    document = _resolved({"vehicle": {"aerodynamics": polar, "angle_of_attack": None}})
    assert document["vehicle"]["aerodynamics"]["model"] == "parabolic_polar"
    assert "cl_coefficients" not in document["vehicle"]["aerodynamics"]
    assert document["vehicle"].get("angle_of_attack") is None
    with pytest.raises(ApiError, match=r"vehicle\.angle_of_attack: a parabolic polar"):
        _resolved({"vehicle": {"aerodynamics": polar}})
    range_spec = {"kind": "range", "lo": 10, "hi": 20}
    document = _resolved({"terminal": {"latitude_deg": range_spec}})
    assert document["terminal"]["latitude_deg"] == range_spec
    fixed_time = get_scenario(NFZ_SCENARIO).problem["final_time"]
    assert fixed_time["kind"] == "fixed"
    document = _resolved({"final_time": {"kind": "free"}}, NFZ_SCENARIO)
    assert document["final_time"] == {"kind": "free", "max_s": None}


def test_switching_the_method_drops_the_old_method_s_options() -> None:
    """``method`` in overrides and the ``method`` shortcut follow the same rule, in that order."""
    scenario_method = get_scenario(SCENARIO).problem["method"]
    assert scenario_method["name"] == "energy-scp"
    document = _resolved({"method": {"name": "foh-ptr"}})
    assert document["method"]["name"] == "foh-ptr"
    assert document["method"]["nodes"] != scenario_method["nodes"]  # foh-ptr's default
    document = _resolved({"method": {"name": "foh-ptr"}}, method={"nodes": 30})
    assert (document["method"]["name"], document["method"]["nodes"]) == ("foh-ptr", 30)
    document = _resolved(
        {"method": {"name": "foh-ptr", "nodes": 30}}, method={"name": "energy-scp"}
    )
    assert document["method"] == EnergyScpOptions().model_dump(mode="json")  # its defaults
    assert _resolved({"method": None})["method"]["name"] == "auto"  # no method: auto chooses


def test_null_removes_fields_and_arrays_replace_whole() -> None:
    zones = get_scenario(NFZ_SCENARIO).problem["no_fly_zones"]
    assert zones
    assert _resolved({"no_fly_zones": None}, NFZ_SCENARIO)["no_fly_zones"] == []
    zone = {"center_latitude_deg": 40, "center_longitude_deg": 5, "radius_km": 100}
    replaced = _resolved({"no_fly_zones": [zone]}, NFZ_SCENARIO)["no_fly_zones"]
    assert [z["center_latitude_deg"] for z in replaced] == [40]
    assert replaced[0]["metric"] == "great_circle"  # not merged with the old zone's lat_lon
    assert _resolved({"waypoints": None})["waypoints"] == []  # absent in the scenario: no-op
    planet = _resolved({"planet": {"g0_m_s2": None, "mu_m3_s2": 3.986004418e14}})["planet"]
    assert (planet["g0_m_s2"], planet["mu_m3_s2"]) == (None, 3.986004418e14)


def test_errors_name_the_path_the_override_wrote() -> None:
    body = {"scenario": _scenario_name()}
    cases: list[tuple[dict[str, Any], str, str]] = [
        (
            {"planet": {"atmosphere": {"scale_height_m": -1}}},
            "planet.atmosphere.scale_height_m",
            "greater_than",
        ),
        (
            {"planet": {"atmosphere": {"scale_height_m": None}}},
            "planet.atmosphere.scale_height_m",
            "missing",
        ),
        (
            {"planet": {"atmosphere": {"model": "us76", "scale_height_m": 8000}}},
            "planet.atmosphere.scale_height_m",
            "extra_forbidden",
        ),
        ({"vehicle": {"mass_kg": None}}, "vehicle.mass_kg", "missing"),
        ({"planet": None}, "planet", "missing"),
        (
            {"terminal": {"latitude_deg": {"kind": "range", "lo": 10}}},
            "terminal.latitude_deg.hi",
            "missing",
        ),
    ]
    for overrides, field, code in cases:
        error, _ = _issues({**body, "overrides": overrides})
        assert error.code == "invalid_problem"
        assert [(i["field"], i["code"]) for i in error.issues or []] == [(field, code)], overrides


def test_overrides_must_be_an_object() -> None:
    for overrides in (None, "us76", 3, [US76]):
        error, fields = _issues({"scenario": _scenario_name(), "overrides": overrides})
        assert (error.code, fields) == ("invalid_request", ["overrides"])
    error, fields = _issues({"scenario": _scenario_name(), "method": "foh-ptr"})
    assert (error.code, fields) == ("invalid_request", ["method"])
