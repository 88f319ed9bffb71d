"""Tests of the problem contract: the reference document validates, and each rejection names
the offending field and the reason."""

from __future__ import annotations

import copy
import json
import math
import subprocess
import sys
from typing import Any

import pytest
from pydantic import ValidationError

from app.schemas import (
    MAX_NO_FLY_ZONES,
    MAX_NODES,
    METHOD_NAMES,
    METHOD_OPTIONS,
    AutoOptions,
    EnergyScpOptions,
    FixedSpec,
    FreeSpec,
    NoFlyZone,
    Planet,
    ProblemDocument,
    RangeSpec,
    SoftSpec,
    issues_from_validation_error,
)
from app.schemas.geometry import central_angle_deg, great_circle_distance_m

# Paper 000 (Jung, Kim, Choi, Lee), simulation 1, exactly as the contract states it.
REFERENCE_JSON = """
{"name": "rlv-min-heat-load", "vehicle": {"mass_kg": 105000, "reference_area_m2": 300,
 "aerodynamics": {"model": "polynomial", "cl_coefficients": [-0.041065, 0.016292, 0.0002602],
   "cd_coefficients": [0.080505, -0.03026, 0.86495], "cd_argument": "cl"},
 "angle_of_attack": {"mode": "velocity_schedule"}},
 "planet": {"radius_m": 6378140, "g0_m_s2": 9.81, "rotation": false,
   "atmosphere": {"model": "exponential", "density_sea_level_kg_m3": 1.225,
     "scale_height_m": 8420}},
 "initial_state": {"altitude_m": 105000, "longitude_deg": 0, "latitude_deg": 0,
   "velocity_m_s": 7449.81, "flight_path_angle_deg": -0.5, "heading_deg": 0},
 "terminal": {"altitude_m": 30000, "longitude_deg": {"kind": "soft", "value": 15, "weight": 200},
   "latitude_deg": {"kind": "soft", "value": 70, "weight": 200}, "flight_path_angle_deg": -10,
   "heading_deg": 15},
 "energy": {"initial": 0.5403, "final": 0.9888},
 "path_constraints": {"heat_rate": {"max_W_m2": 1.0e6, "k_q": 9.4369e-5},
   "dynamic_pressure": {"max_Pa": 17000}, "load_factor": {"max_g": 3.5}},
 "control_limits": {"bank_max_deg": 80}, "objective": "min_heat_load",
 "method": {"name": "energy-scp", "nodes": 120}}
"""


def reference() -> dict[str, Any]:
    """A fresh, mutable copy of the reference document."""
    return copy.deepcopy(json.loads(REFERENCE_JSON))


def issues_of(document: dict[str, Any]) -> dict[str, list[str]]:
    """Validate ``document``, which must fail, and map each dotted field path to its messages."""
    with pytest.raises(ValidationError) as caught:
        ProblemDocument.model_validate(document)
    found: dict[str, list[str]] = {}
    for issue in issues_from_validation_error(caught.value):
        found.setdefault(issue.field, []).append(issue.message)
    return found


def assert_issue(found: dict[str, list[str]], field: str, reason: str) -> None:
    """Assert that ``field`` has an issue whose message contains ``reason``."""
    assert field in found, f"no issue at {field!r}; issues: {found}"
    assert any(reason in message for message in found[field]), found[field]


# ---------------------------------------------------------------- the reference document


def test_reference_document_validates_with_contract_defaults() -> None:
    problem = ProblemDocument.model_validate_json(REFERENCE_JSON)
    assert problem.schema_version == "1.0"
    assert problem.vehicle.aerodynamics.model == "polynomial"
    assert problem.terminal.altitude_m == FixedSpec(value=30000.0)
    assert problem.terminal.velocity_m_s == FreeSpec()
    assert problem.terminal.longitude_deg == SoftSpec(value=15.0, weight=200.0)
    assert [t.name for t in problem.objective.terms] == ["min_heat_load"]
    assert isinstance(problem.method, EnergyScpOptions)
    assert problem.method.post_correction_step == 0.7
    assert problem.method.stop_tolerance.heading_deg == 1.0
    assert problem.planet.surface_gravity_m_s2 == 9.81


def test_reference_document_round_trips_through_json() -> None:
    problem = ProblemDocument.model_validate_json(REFERENCE_JSON)
    assert ProblemDocument.model_validate(problem.model_dump()) == problem
    assert ProblemDocument.model_validate_json(problem.model_dump_json()) == problem
    assert ProblemDocument.model_validate(json.loads(problem.model_dump_json())) == problem


def test_packaged_example_is_the_reference_document() -> None:
    schema = ProblemDocument.model_json_schema()
    (example,) = schema["examples"]
    assert ProblemDocument.model_validate(example) == ProblemDocument.model_validate(reference())


def test_every_field_of_the_contract_has_a_description() -> None:
    schema = ProblemDocument.model_json_schema()
    models = {"ProblemDocument": schema, **schema["$defs"]}
    missing = [
        f"{model}.{name}"
        for model, definition in models.items()
        for name, prop in definition.get("properties", {}).items()
        if not prop.get("description")
    ]
    assert missing == []


def test_schemas_import_neither_fastapi_nor_celery() -> None:
    code = "import sys, app.schemas; print(sorted({'fastapi', 'celery'} & set(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


# ---------------------------------------------------------------- shorthands and defaults


def test_plain_number_terminal_spec_becomes_fixed() -> None:
    document = reference()
    document["terminal"]["velocity_m_s"] = 900
    problem = ProblemDocument.model_validate(document)
    assert problem.terminal.velocity_m_s == FixedSpec(value=900.0)
    assert problem.terminal.velocity_m_s.target() == 900.0


def test_boolean_is_not_a_terminal_number() -> None:
    document = reference()
    document["terminal"]["velocity_m_s"] = True
    assert "terminal.velocity_m_s" in issues_of(document)


def test_string_objective_becomes_one_term_of_weight_one() -> None:
    problem = ProblemDocument.model_validate(reference())
    assert len(problem.objective.terms) == 1
    assert problem.objective.terms[0].name == "min_heat_load"
    assert problem.objective.terms[0].weight == 1.0


def test_method_defaults_to_auto() -> None:
    """A document without a method, or a method object without a name, lets auto choose."""
    document = reference()
    del document["method"]
    assert ProblemDocument.model_validate(document).method == AutoOptions()
    document["method"] = {"nodes": 60}
    method = ProblemDocument.model_validate(document).method
    assert isinstance(method, AutoOptions)
    assert method.nodes == 60
    assert method.options_for("energy-scp") == EnergyScpOptions(nodes=60)
    assert "auto" not in METHOD_NAMES  # the methods auto chooses among
    assert METHOD_OPTIONS["energy-scp"] is EnergyScpOptions
    document["method"] = {"name": "energy-scp"}  # a named method stays as it was
    assert ProblemDocument.model_validate(document).method == EnergyScpOptions()


def test_auto_overrides_are_checked_against_each_methods_options() -> None:
    document = reference()
    document["method"] = {
        "overrides": {"foh-ptr": {"nodes": 2}, "nope": {}, "cheb-scvx": {"name": "hp-scp"}}
    }
    found = issues_of(document)
    assert sorted(found) == [
        "method.overrides.cheb-scvx.name",
        "method.overrides.foh-ptr.nodes",
        "method.overrides.nope",
    ]
    assert_issue(found, "method.overrides.nope", "unknown method 'nope'; auto tries energy-scp")
    assert_issue(found, "method.overrides.foh-ptr.nodes", "greater than or equal to 9")


def test_mu_alone_replaces_default_g0() -> None:
    planet = Planet.model_validate(
        {"mu_m3_s2": 3.986004418e14, "atmosphere": {"model": "us76"}, "radius_m": 6378137.0}
    )
    assert planet.g0_m_s2 is None
    # Relative 1e-12: one division of exact inputs, a few ulps of rounding at most.
    assert planet.surface_gravity_m_s2 == pytest.approx(3.986004418e14 / 6378137.0**2, rel=1e-12)
    assert Planet.model_validate(planet.model_dump()) == planet


def test_terminal_spec_helpers() -> None:
    assert RangeSpec(lo=10.0, hi=20.0).target() == 15.0
    assert RangeSpec(lo=10.0, hi=20.0).contains(20.5, tol=0.5)
    assert not RangeSpec(lo=10.0, hi=20.0).contains(20.6, tol=0.5)
    assert FreeSpec().target() is None
    assert FreeSpec().contains(1e9)
    assert FixedSpec(value=3.0).contains(3.0)
    assert not FixedSpec(value=3.0).contains(3.1, tol=0.05)
    assert SoftSpec(value=70.0, weight=200.0).contains(70.5, tol=0.6)


def test_haversine_matches_known_separations() -> None:
    radius = 6378140.0
    # Absolute 1e-9 deg: a handful of double-precision roundings on angles of order 100 deg.
    assert central_angle_deg(0.0, 0.0, 0.0, 90.0) == pytest.approx(90.0, abs=1e-9)
    assert central_angle_deg(-45.0, 10.0, 45.0, 10.0) == pytest.approx(90.0, abs=1e-9)
    assert central_angle_deg(89.0, 0.0, 89.0, 180.0) == pytest.approx(2.0, abs=1e-9)
    # Relative 1e-12: the same computation scaled by the radius.
    assert great_circle_distance_m(0.0, 0.0, 0.0, 180.0, radius) == pytest.approx(
        math.pi * radius, rel=1e-12
    )


def test_zone_radius_in_km_and_deg_agree() -> None:
    radius = 6378140.0
    km = NoFlyZone(center_latitude_deg=0.0, center_longitude_deg=0.0, radius_km=1000.0)
    deg = NoFlyZone(
        center_latitude_deg=0.0,
        center_longitude_deg=0.0,
        radius_deg=math.degrees(1.0e6 / radius),
    )
    # Relative 1e-12: both are one exact arithmetic conversion of the same arc.
    assert km.radius_rad(radius) == pytest.approx(deg.radius_rad(radius), rel=1e-12)


def test_lat_lon_zone_is_narrower_east_west() -> None:
    """Paper 002's zone metric (dlat, dlon in degrees): at 60 deg latitude a point 4 deg of
    longitude off the centre is 2 deg of arc away, inside a 3 deg great-circle zone but outside
    the same zone measured in lat-lon degrees."""
    radius = 6378000.0
    common = {"center_latitude_deg": 60.0, "center_longitude_deg": 0.0, "radius_deg": 3.0}
    sphere = NoFlyZone(**common)
    plane = NoFlyZone(**common, metric="lat_lon")
    assert sphere.contains_point(60.0, 4.0, radius)
    assert not plane.contains_point(60.0, 4.0, radius)
    assert plane.contains_point(62.9, 0.0, radius) and sphere.contains_point(62.9, 0.0, radius)


# ---------------------------------------------------------------- rejections


@pytest.mark.parametrize("token", ["NaN", "Infinity", "-Infinity"])
def test_non_finite_number_in_json_is_rejected(token: str) -> None:
    text = REFERENCE_JSON.replace('"mass_kg": 105000', f'"mass_kg": {token}')
    assert text != REFERENCE_JSON
    with pytest.raises(ValidationError) as caught:
        ProblemDocument.model_validate_json(text)
    issues = issues_from_validation_error(caught.value)
    assert [(i.field, i.code) for i in issues] == [("vehicle.mass_kg", "finite_number")]
    assert "finite" in issues[0].message


def test_non_finite_number_inside_a_union_names_the_field() -> None:
    text = REFERENCE_JSON.replace('"scale_height_m": 8420', '"scale_height_m": NaN')
    with pytest.raises(ValidationError) as caught:
        ProblemDocument.model_validate_json(text)
    (issue,) = issues_from_validation_error(caught.value)
    assert issue.field == "planet.atmosphere.scale_height_m"
    assert issue.code == "finite_number"


@pytest.mark.parametrize("field", ["mass_kg", "reference_area_m2"])
@pytest.mark.parametrize("value", [0, -1.0])
def test_non_positive_mass_and_area_are_rejected(field: str, value: float) -> None:
    document = reference()
    document["vehicle"][field] = value
    assert_issue(issues_of(document), f"vehicle.{field}", "greater than 0")


@pytest.mark.parametrize(
    "spec", [200000, {"kind": "range", "lo": 120000, "hi": 130000}], ids=["fixed", "range"]
)
def test_terminal_altitude_above_initial_is_rejected(spec: Any) -> None:
    document = reference()
    document["terminal"]["altitude_m"] = spec
    assert_issue(
        issues_of(document), "terminal.altitude_m", "is above the initial altitude (105000 m)"
    )


def test_energies_out_of_order_are_rejected() -> None:
    document = reference()
    document["energy"] = {"initial": 0.9888, "final": 0.5403}
    assert_issue(issues_of(document), "energy.final", "energies out of order")


def test_range_with_lo_above_hi_is_rejected() -> None:
    document = reference()
    document["terminal"]["velocity_m_s"] = {"kind": "range", "lo": 1000, "hi": 800}
    assert_issue(issues_of(document), "terminal.velocity_m_s", "lo > hi")


@pytest.mark.parametrize("bank", [0, 95])
def test_bank_limit_outside_zero_to_ninety_is_rejected(bank: float) -> None:
    document = reference()
    document["control_limits"]["bank_max_deg"] = bank
    assert_issue(
        issues_of(document), "control_limits.bank_max_deg", "bank limit must be in (0, 90] degrees"
    )


@pytest.mark.parametrize(
    ("limits", "field", "reason"),
    [
        ({"bank_max_deg": 10, "bank_min_deg": 20}, "bank_min_deg", "must be below bank_max_deg"),
        ({"bank_max_deg": 10, "bank_min_deg": 10}, "bank_min_deg", "must be below bank_max_deg"),
        ({"bank_min_deg": -95}, "bank_min_deg", "bank lower bound must be in [-90, 90)"),
    ],
)
def test_bank_range_out_of_order_or_range_is_rejected(
    limits: dict[str, float], field: str, reason: str
) -> None:
    document = reference()
    document["control_limits"] = limits
    assert_issue(issues_of(document), f"control_limits.{field}", reason)


def test_asymmetric_bank_range_and_its_default() -> None:
    document = reference()
    document["control_limits"] = {"bank_max_deg": 1, "bank_min_deg": -89}
    assert ProblemDocument.model_validate(document).control_limits.bank_lower_deg == -89
    document["control_limits"] = {"bank_max_deg": 70}
    assert ProblemDocument.model_validate(document).control_limits.bank_lower_deg == -70


@pytest.mark.parametrize(
    ("where", "field"),
    [
        (("initial_state", "bank_deg"), "initial_state.bank_deg"),
        (("method", "initial_bank_deg"), "method.initial_bank_deg"),
    ],
)
def test_initial_bank_outside_the_bank_range_is_rejected(
    where: tuple[str, str], field: str
) -> None:
    document = reference()
    document["control_limits"] = {"bank_max_deg": 1, "bank_min_deg": -89}
    document["method"] = {"name": "foh-ptr"}
    document[where[0]][where[1]] = 20
    assert_issue(issues_of(document), field, "outside the bank range [-89, 1] deg")


def test_no_fly_zone_containing_initial_point_is_rejected() -> None:
    document = reference()
    document["no_fly_zones"] = [
        {"center_latitude_deg": 20, "center_longitude_deg": 5, "radius_km": 300},
        {"center_latitude_deg": 1, "center_longitude_deg": 1, "radius_km": 200},
    ]
    found = issues_of(document)
    assert_issue(found, "no_fly_zones[1]", "contains the initial point")
    assert "no_fly_zones[0]" not in found


def test_no_fly_zone_boundary_uses_great_circle_distance() -> None:
    # The initial point is 1 deg of arc (111.3 km on this sphere) from the center: a 111 km
    # zone misses it, a 112 km zone contains it.
    document = reference()
    zone = {"center_latitude_deg": 1, "center_longitude_deg": 0}
    document["no_fly_zones"] = [{**zone, "radius_km": 111.0}]
    ProblemDocument.model_validate(document)
    document["no_fly_zones"] = [{**zone, "radius_km": 112.0}]
    assert_issue(issues_of(document), "no_fly_zones[0]", "contains the initial point")


def test_no_fly_zone_containing_target_is_rejected() -> None:
    document = reference()
    document["no_fly_zones"] = [
        {"name": "polar", "center_latitude_deg": 69, "center_longitude_deg": 14, "radius_deg": 2}
    ]
    assert_issue(issues_of(document), "no_fly_zones[0]", "contains the target point")


def test_nodes_over_the_cap_are_rejected() -> None:
    document = reference()
    document["method"]["nodes"] = MAX_NODES + 1
    assert_issue(issues_of(document), "method.nodes", f"less than or equal to {MAX_NODES}")


def test_more_no_fly_zones_than_the_cap_are_rejected() -> None:
    document = reference()
    zone = {"center_latitude_deg": -40, "center_longitude_deg": -100, "radius_km": 10}
    document["no_fly_zones"] = [dict(zone) for _ in range(MAX_NO_FLY_ZONES + 1)]
    assert_issue(issues_of(document), "no_fly_zones", f"at most {MAX_NO_FLY_ZONES} items")


@pytest.mark.parametrize(
    ("path", "field"),
    [
        ((), "colour"),
        (("vehicle",), "colour"),
        (("vehicle", "aerodynamics"), "colour"),
        (("terminal", "longitude_deg"), "colour"),
    ],
    ids=["top", "nested", "in-union", "in-terminal-spec"],
)
def test_unknown_fields_are_rejected(path: tuple[str, ...], field: str) -> None:
    document = reference()
    target = document
    for key in path:
        target = target[key]
    target[field] = "blue"
    dotted = ".".join((*path, field))
    assert_issue(issues_of(document), dotted, "unknown field")


def test_unknown_method_name_is_rejected() -> None:
    document = reference()
    document["method"] = {"name": "magic"}
    found = issues_of(document)
    assert_issue(found, "method.name", "'magic'")
    assert_issue(found, "method.name", "energy-scp")


def test_duplicate_waypoint_order_is_rejected() -> None:
    document = reference()
    document["waypoints"] = [
        {"latitude_deg": 20, "longitude_deg": 5, "radius_km": 50, "order": 0},
        {"latitude_deg": 40, "longitude_deg": 10, "radius_km": 50, "order": 0},
    ]
    assert_issue(issues_of(document), "waypoints[1].order", "orders must be unique")


@pytest.mark.parametrize("radii", [{"radius_km": 100, "radius_deg": 1}, {}], ids=["both", "none"])
def test_zone_needs_exactly_one_radius(radii: dict[str, float]) -> None:
    document = reference()
    document["no_fly_zones"] = [{"center_latitude_deg": 40, "center_longitude_deg": 5, **radii}]
    assert_issue(
        issues_of(document),
        "no_fly_zones[0].radius_km",
        "exactly one of radius_km and radius_deg",
    )


def test_duplicate_objective_term_is_rejected() -> None:
    document = reference()
    document["objective"] = {"terms": [{"name": "min_time"}, {"name": "min_time", "weight": 2}]}
    assert_issue(issues_of(document), "objective.terms[1].name", "more than once")


def test_fixed_final_time_must_exceed_initial_time() -> None:
    document = reference()
    document["initial_state"]["time_s"] = 100
    document["final_time"] = {"kind": "fixed", "value_s": 50}
    assert_issue(issues_of(document), "final_time.value_s", "must exceed the initial time")


def test_table_aerodynamics_shape_is_checked() -> None:
    document = reference()
    document["vehicle"]["aerodynamics"] = {
        "model": "table",
        "alpha_deg": [0, 10, 20],
        "mach": [2, 5],
        "cl": [[0.1, 0.1], [0.3, 0.3]],
        "cd": [[0.1, 0.1], [0.2], [0.3, 0.3]],
    }
    found = issues_of(document)
    assert_issue(found, "vehicle.aerodynamics.cl", "expected one per alpha_deg (3)")
    assert_issue(found, "vehicle.aerodynamics.cd[1]", "expected one per mach (2)")


def test_field_errors_are_all_reported_at_once() -> None:
    document = reference()
    document["vehicle"]["mass_kg"] = -5
    document["control_limits"]["bank_max_deg"] = 95
    document["method"]["nodes"] = MAX_NODES + 1
    document["surprise"] = 1
    found = issues_of(document)
    assert {
        "vehicle.mass_kg",
        "control_limits.bank_max_deg",
        "method.nodes",
        "surprise",
    } <= found.keys()


def test_cross_field_errors_are_all_reported_at_once() -> None:
    document = reference()
    document["terminal"]["altitude_m"] = 200000
    document["no_fly_zones"] = [
        {"center_latitude_deg": 0, "center_longitude_deg": 0, "radius_km": 100}
    ]
    document["final_time"] = {"kind": "fixed", "value_s": 0.0001}
    document["initial_state"]["time_s"] = 10
    found = issues_of(document)
    assert_issue(found, "terminal.altitude_m", "is above the initial altitude")
    assert_issue(found, "no_fly_zones[0]", "contains the initial point")
    assert_issue(found, "final_time.value_s", "must exceed the initial time")


def test_second_order_step_needs_the_exact_maps() -> None:
    document = reference()
    document["method"] = {"name": "foh-ptr", "discretization": "trapezoid"}
    assert_issue(issues_of(document), "method.second_order", "needs discretization exact_foh")
    document["method"]["second_order"] = False
    ProblemDocument.model_validate(document)


def test_a_union_tag_error_names_the_tag_field_and_the_allowed_values() -> None:
    from app.schemas import issues_from_validation_error
    from worker.solver.scenarios import get_scenario

    for atmosphere, code in (({"model": "us77"}, "union_tag_invalid"), ({}, "union_tag_not_found")):
        raw = copy.deepcopy(get_scenario("rlv-min-heat-load").problem)
        raw["planet"]["atmosphere"] = atmosphere
        with pytest.raises(ValidationError) as caught:
            ProblemDocument.model_validate(raw)
        (issue,) = issues_from_validation_error(caught.value)
        assert (issue.field, issue.code) == ("planet.atmosphere.model", code)
        if code == "union_tag_invalid":
            assert "'us77'" in issue.message and "'exponential', 'us76'" in issue.message
