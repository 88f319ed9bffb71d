"""Propulsion, phases and the minimum-propellant objective in the problem contract: a two-phase
skip entry with thrust validates, each rule refuses at the field it names, every document
without them means what it meant, and the methods that cannot fly them refuse them."""

from __future__ import annotations

import copy
import dataclasses
import json
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from pydantic import ValidationError

from app.main import create_app
from app.schemas import (
    MAX_PHASES,
    STANDARD_GRAVITY_M_S2,
    FixedSpec,
    FreeSpec,
    ProblemDocument,
    Propulsion,
    RangeSpec,
    issues_from_validation_error,
)
from app.settings import Settings
from tests.unit.test_service_api import RecordingDispatcher, assert_error
from worker.solver.methods import METHODS, check_support, list_methods
from worker.solver.methods import registry as method_registry
from worker.solver.scenarios import list_scenarios

CONTRACT = Path(__file__).resolve().parents[2] / "docs" / "problem-contract.md"
EXISTING_METHODS = ("energy-scp", "foh-ptr", "hp-scp", "cheb-scvx")
SINGLE_PHASE = "solves single-phase problems without propulsion"


def _documented_example() -> dict[str, Any]:
    """The two-phase example of docs/problem-contract.md."""
    text = CONTRACT.read_text(encoding="utf-8")
    section = text.split("## Example (two phases with thrust, minimum propellant)", 1)[1]
    block = re.search(r"```json\n(.*?)\n```", section, re.DOTALL)
    assert block is not None
    document: dict[str, Any] = json.loads(block.group(1))
    return document


SKIP_ENTRY = _documented_example()


def skip_entry() -> dict[str, Any]:
    """A fresh, mutable copy of the two-phase skip entry."""
    return copy.deepcopy(SKIP_ENTRY)


def unpowered(document: dict[str, Any]) -> dict[str, Any]:
    """``document`` without propulsion: coasting phases, minimum time."""
    del document["vehicle"]["propulsion"]
    for phase in document["phases"]:
        phase["thrust_max_n"] = 0
    document["objective"] = "min_time"
    return document


def issues_of(document: dict[str, Any]) -> list[tuple[str, str, str]]:
    """Validate ``document``, which must fail: its (field, code, message) issues."""
    with pytest.raises(ValidationError) as caught:
        ProblemDocument.model_validate(document)
    return [(i.field, i.code, i.message) for i in issues_from_validation_error(caught.value)]


def assert_issue(document: dict[str, Any], field: str, code: str, *words: str) -> None:
    """Assert that ``document`` is refused at ``field`` with ``code`` and a message holding
    ``field``'s own name and each of ``words``."""
    found = issues_of(document)
    at = [(c, m) for f, c, m in found if f == field]
    assert at, f"no issue at {field!r}; issues: {found}"
    own = str(field).rsplit(".", 1)[-1].split("[")[0]
    assert any(c == code and own in m and all(w in m for w in words) for c, m in at), (
        f"{field}: {at}"
    )


# ---------------------------------------------------------------- a valid two-phase document


def test_two_phase_skip_entry_with_propulsion_validates() -> None:
    problem = ProblemDocument.model_validate(skip_entry())
    engine = problem.vehicle.propulsion
    assert isinstance(engine, Propulsion)
    assert (engine.max_thrust_n, engine.isp_s, engine.thrust_lag_s) == (2.0e6, 316.0, 1.0)
    assert (engine.initial_thrust_n, engine.dry_mass_kg, engine.lagged) == (0.0, None, True)
    assert engine.mass_flow_kg_s(2.0e6) == pytest.approx(2.0e6 / (316.0 * 9.80665))
    assert STANDARD_GRAVITY_M_S2 == 9.80665
    descent, exit_ = problem.phases
    assert (descent.name, descent.thrust_max_n, exit_.thrust_max_n) == ("descent", 0.0, None)
    assert (descent.duration_s.min_s, descent.duration_s.max_s) == (500.0, 5000.0)
    assert descent.end.altitude_m == FixedSpec(value=50000.0)
    assert descent.end.velocity_m_s == RangeSpec(lo=3000.0, hi=10000.0)
    assert descent.angle_of_attack_deg is None and descent.path_constraints is None
    assert exit_.angle_of_attack_deg is not None and exit_.angle_of_attack_deg.max_deg == 90.0
    assert exit_.end.heading_deg == FreeSpec()
    assert problem.objective.names() == ["min_propellant"]
    assert problem.final_conditions() is exit_.end
    assert ProblemDocument.model_validate(problem.model_dump()) == problem
    assert ProblemDocument.model_validate_json(problem.model_dump_json()) == problem


def test_phase_defaults_and_optional_overrides() -> None:
    document = skip_entry()
    document["vehicle"]["propulsion"].update(initial_thrust_n=1.0e6, dry_mass_kg=70000)
    document["phases"] = [{"name": "only", "duration_s": {"min_s": 1, "max_s": 3000}}]
    document["phases"][0].update(
        bank_min_deg=-30,
        bank_max_deg=60,
        thrust_max_n=2.0e6,
        path_constraints={"dynamic_pressure": {"max_Pa": 20000}},
    )
    problem = ProblemDocument.model_validate(document)
    (phase,) = problem.phases
    assert phase.end.specs() == {name: FreeSpec() for name in phase.end.specs()}
    assert phase.bank_range_deg(-90.0, 90.0) == (-30.0, 60.0)
    assert phase.path_constraints is not None and phase.path_constraints.heat_rate is None
    assert problem.vehicle.propulsion is not None
    assert problem.vehicle.propulsion.dry_mass_kg == 70000.0


def test_unpowered_phases_and_powered_single_phase_validate() -> None:
    ProblemDocument.model_validate(unpowered(skip_entry()))
    document = skip_entry()
    del document["phases"]
    document["terminal"] = {"altitude_m": 30000}
    ProblemDocument.model_validate(document)  # propulsion without phases: one powered phase


def test_every_new_field_has_a_description() -> None:
    definitions = ProblemDocument.model_json_schema()["$defs"]
    for model in ("Propulsion", "Phase", "DurationBounds", "AngleBounds"):
        properties = definitions[model]["properties"]
        assert all(p.get("description") for p in properties.values()), model
    assert "phases" not in ProblemDocument.model_json_schema().get("required", [])
    assert "propulsion" not in definitions["Vehicle"].get("required", [])


# ---------------------------------------------------------------- field rules


@pytest.mark.parametrize(
    ("field", "value", "code"),
    [
        ("max_thrust_n", 0, "greater_than"),
        ("max_thrust_n", 2e8, "less_than_equal"),
        ("isp_s", 0, "greater_than"),
        ("isp_s", 0.5, "below_minimum"),
        ("isp_s", 2e5, "less_than_equal"),
        ("thrust_lag_s", -1, "greater_than_equal"),
        ("thrust_lag_s", 1e-6, "below_minimum"),
        ("initial_thrust_n", -1, "greater_than_equal"),
        ("dry_mass_kg", 0, "greater_than"),
    ],
)
def test_propulsion_fields_out_of_range_are_refused(field: str, value: float, code: str) -> None:
    document = skip_entry()
    document["vehicle"]["propulsion"][field] = value
    found = issues_of(document)
    assert (f"vehicle.propulsion.{field}", code) in {(f, c) for f, c, _ in found}, found


@pytest.mark.parametrize("lag", [None, 0])
def test_no_thrust_lag_means_the_thrust_is_the_command(lag: float | None) -> None:
    document = skip_entry()
    document["vehicle"]["propulsion"]["thrust_lag_s"] = lag
    engine = ProblemDocument.model_validate(document).vehicle.propulsion
    assert engine is not None and not engine.lagged


def test_initial_thrust_above_the_largest_is_refused() -> None:
    document = skip_entry()
    document["vehicle"]["propulsion"]["initial_thrust_n"] = 3.0e6
    assert_issue(
        document, "vehicle.propulsion.initial_thrust_n", "thrust_limit", "max_thrust_n", "2e+06"
    )


@pytest.mark.parametrize("dry", [90719, 100000])
def test_dry_mass_at_or_above_the_initial_mass_is_refused(dry: float) -> None:
    document = skip_entry()
    document["vehicle"]["propulsion"]["dry_mass_kg"] = dry
    assert_issue(document, "vehicle.propulsion.dry_mass_kg", "dry_mass_order", "mass_kg")


def test_more_phases_than_the_cap_are_refused() -> None:
    document = skip_entry()
    template = document["phases"][0]
    document["phases"] = [{**template, "name": f"leg {i}"} for i in range(MAX_PHASES + 1)]
    found = issues_of(document)
    assert ("phases", "too_long") in {(f, c) for f, c, _ in found}, found
    document["phases"] = document["phases"][:MAX_PHASES]
    ProblemDocument.model_validate(document)


@pytest.mark.parametrize(
    ("change", "field", "code"),
    [
        (lambda p: p.update(name=""), "phases[0].name", "string_too_short"),
        (lambda p: p.update(name="x" * 65), "phases[0].name", "string_too_long"),
        (lambda p: p.pop("name"), "phases[0].name", "missing"),
        (lambda p: p.pop("duration_s"), "phases[0].duration_s", "missing"),
        (lambda p: p["duration_s"].update(min_s=0), "phases[0].duration_s.min_s", "greater_than"),
        (lambda p: p.update(bank_min_deg=-91), "phases[0].bank_min_deg", "greater_than_equal"),
        (lambda p: p.update(bank_max_deg=91), "phases[0].bank_max_deg", "less_than_equal"),
        (lambda p: p.update(thrust_max_n=-1), "phases[0].thrust_max_n", "greater_than_equal"),
        (
            lambda p: p.update(angle_of_attack_deg={"min_deg": -91, "max_deg": 10}),
            "phases[0].angle_of_attack_deg.min_deg",
            "greater_than_equal",
        ),
        (
            lambda p: p["end"].update(altitude_m={"kind": "range", "lo": 5, "hi": 1}),
            "phases[0].end.altitude_m",
            "range_order",
        ),
        (lambda p: p.update(bogus=1), "phases[0].bogus", "extra_forbidden"),
    ],
)
def test_phase_fields_out_of_range_are_refused(change: Any, field: str, code: str) -> None:
    document = skip_entry()
    change(document["phases"][0])
    found = issues_of(document)
    assert (field, code) in {(f, c) for f, c, _ in found}, found


def test_duration_bounds_out_of_order_are_refused() -> None:
    document = skip_entry()
    document["phases"][1]["duration_s"] = {"min_s": 100, "max_s": 100}
    assert_issue(document, "phases[1].duration_s.max_s", "bounds_order", "min_s")


def test_angle_of_attack_bounds_out_of_order_are_refused() -> None:
    document = skip_entry()
    document["phases"][1]["angle_of_attack_deg"] = {"min_deg": 20, "max_deg": 10}
    assert_issue(document, "phases[1].angle_of_attack_deg.max_deg", "bounds_order", "min_deg")


def test_phase_bank_bounds_out_of_order_are_refused() -> None:
    document = skip_entry()
    document["phases"][0].update(bank_min_deg=10, bank_max_deg=10)
    assert_issue(document, "phases[0].bank_min_deg", "bank_limit", "bank_max_deg")


@pytest.mark.parametrize(
    ("bound", "value", "limits"),
    [
        ("bank_min_deg", 85, {"bank_max_deg": 80}),  # above control_limits.bank_max_deg
        ("bank_max_deg", -85, {"bank_max_deg": 80}),  # below its lower bound -80
        ("bank_max_deg", -60, {"bank_max_deg": 1, "bank_min_deg": -50}),
    ],
)
def test_one_phase_bank_bound_must_leave_a_range_with_control_limits(
    bound: str, value: float, limits: dict[str, float]
) -> None:
    document = skip_entry()
    document["control_limits"] = limits
    document["phases"][0][bound] = value
    assert_issue(document, f"phases[0].{bound}", "bank_limit", "control_limits", "empty")


def test_phase_names_are_unique() -> None:
    document = skip_entry()
    document["phases"][1]["name"] = "descent"
    assert_issue(document, "phases[1].name", "duplicate_phase_name", "phases[0]", "unique")


# ---------------------------------------------------------------- document rules with phases


@pytest.mark.parametrize(
    "spec",
    [10, {"kind": "range", "lo": 1, "hi": 2}, {"kind": "soft", "value": 1, "weight": 1}],
)
@pytest.mark.parametrize("name", ["altitude_m", "velocity_m_s", "heading_deg"])
def test_terminal_conditions_must_be_free_with_phases(name: str, spec: Any) -> None:
    document = skip_entry()
    document["terminal"] = {name: spec}
    assert_issue(
        document, f"terminal.{name}", "terminal_with_phases", "last phase's end", "phases[1].end"
    )


def test_fixed_final_time_is_refused_with_phases() -> None:
    document = skip_entry()
    document["final_time"] = {"kind": "fixed", "value_s": 1600}
    assert_issue(document, "final_time", "final_time_with_phases", "duration_s")


def test_latest_final_time_is_refused_with_phases() -> None:
    document = skip_entry()
    document["final_time"] = {"kind": "free", "max_s": 1600}
    assert_issue(document, "final_time.max_s", "final_time_with_phases", "duration_s")


def test_energy_bounds_are_refused_with_phases() -> None:
    document = skip_entry()
    document["energy"] = {"initial": 0.5, "final": 0.9}
    assert_issue(document, "energy", "energy_with_phases", "phases")


@pytest.mark.parametrize(
    "attack", [{"mode": "constant", "alpha_deg": 40}, {"mode": "velocity_schedule"}]
)
def test_phases_need_an_optimized_angle_of_attack(attack: dict[str, Any]) -> None:
    document = skip_entry()
    document["vehicle"]["angle_of_attack"] = attack
    assert_issue(
        document,
        "vehicle.angle_of_attack",
        "phases_need_optimized_alpha",
        "optimized",
        "per phase",
        attack["mode"],
    )


def test_a_polar_vehicle_cannot_fly_phases() -> None:
    document = skip_entry()
    del document["vehicle"]["angle_of_attack"]
    document["vehicle"]["aerodynamics"] = {
        "model": "parabolic_polar",
        "cl_star": 0.5,
        "cd0": 0.05,
        "k_induced": 0.5,
    }
    assert_issue(
        document, "vehicle.angle_of_attack", "phases_need_optimized_alpha", "parabolic polar"
    )


def test_phase_thrust_needs_propulsion() -> None:
    document = unpowered(skip_entry())
    document["phases"][1]["thrust_max_n"] = 1.0e6
    assert_issue(
        document, "phases[1].thrust_max_n", "thrust_without_propulsion", "vehicle.propulsion"
    )
    document["phases"][1]["thrust_max_n"] = None  # none = the engine's: no engine, no thrust
    ProblemDocument.model_validate(document)


def test_phase_thrust_above_the_engine_is_refused_naming_both() -> None:
    document = skip_entry()
    document["phases"][1]["thrust_max_n"] = 2.5e6
    assert_issue(
        document, "phases[1].thrust_max_n", "thrust_limit", "2.5e+06", "max_thrust_n", "2e+06"
    )
    document["phases"][1]["thrust_max_n"] = 2.0e6
    ProblemDocument.model_validate(document)


def test_min_propellant_needs_propulsion() -> None:
    document = skip_entry()
    del document["vehicle"]["propulsion"]
    document["phases"][1]["thrust_max_n"] = 0
    assert_issue(
        document, "objective", "propellant_without_propulsion", "min_propellant", "propulsion"
    )


def test_every_phase_rule_is_reported_at_once() -> None:
    document = skip_entry()
    document["terminal"] = {"altitude_m": 80000}
    document["final_time"] = {"kind": "fixed", "value_s": 1600}
    document["energy"] = {"initial": 0.5}
    document["vehicle"]["angle_of_attack"] = {"mode": "constant", "alpha_deg": 40}
    document["phases"][1].update(name="descent", thrust_max_n=3.0e6)
    fields = {f for f, _, _ in issues_of(document)}
    assert {
        "terminal.altitude_m",
        "final_time",
        "energy",
        "vehicle.angle_of_attack",
        "phases[1].name",
        "phases[1].thrust_max_n",
    } <= fields


def test_a_phase_end_above_the_initial_altitude_is_allowed() -> None:
    """A skip climbs back out: the terminal-altitude rule reads ``terminal`` only."""
    document = skip_entry()
    document["phases"][1]["end"]["altitude_m"] = 90000  # above the initial 80 km
    ProblemDocument.model_validate(document)


def test_a_no_fly_zone_around_the_last_phase_target_is_refused() -> None:
    document = skip_entry()
    document["phases"][1]["end"].update(latitude_deg=10, longitude_deg=10)
    document["no_fly_zones"] = [
        {"center_latitude_deg": 10, "center_longitude_deg": 10, "radius_km": 100}
    ]
    found = issues_of(document)
    assert ("no_fly_zones[0]", "zone_contains_target") in {(f, c) for f, c, _ in found}, found


# ---------------------------------------------------------------- existing documents


def _keys(value: Any) -> set[str]:
    """Every member name anywhere in ``value``."""
    if isinstance(value, dict):
        return set(value).union(*(_keys(v) for v in value.values()))
    if isinstance(value, list):
        return set().union(*(_keys(v) for v in value))
    return set()


CLASSIC = [
    s
    for s in list_scenarios()
    if "phases" not in s.problem and "propulsion" not in s.problem["vehicle"]
]
"""The built-in scenarios written without phases and propulsion."""


def test_the_classic_scenarios_are_all_there() -> None:
    names = {s.name for s in CLASSIC}
    assert {"rlv-min-heat-load", "shuttle-max-crossrange", "cav-h-min-time-waypoints"} <= names
    assert len(CLASSIC) >= 9


@pytest.mark.parametrize("scenario", CLASSIC, ids=lambda s: s.name)
def test_every_classic_scenario_means_what_it_meant(scenario: Any) -> None:
    """A document without phases or propulsion is one unpowered phase: it validates unchanged,
    and neither field appears in its sparse dumps (nor changes it when dropped from the full
    one)."""
    raw = copy.deepcopy(scenario.problem)
    problem = ProblemDocument.model_validate(raw)
    assert raw == scenario.problem  # validation changed nothing
    assert problem.phases == [] and problem.vehicle.propulsion is None
    assert problem.final_conditions() is problem.terminal
    given = problem.model_dump(mode="json", exclude_unset=True)
    assert not {"phases", "propulsion"} & _keys(given)
    assert ProblemDocument.model_validate(given) == problem
    assert not {"phases", "propulsion"} & _keys(
        problem.model_dump(mode="json", exclude_defaults=True)
    )
    full = problem.model_dump(mode="json")
    assert full["phases"] == [] and full["vehicle"]["propulsion"] is None
    assert ProblemDocument.model_validate(full) == problem
    del full["phases"], full["vehicle"]["propulsion"]
    assert ProblemDocument.model_validate(full) == problem


def test_no_existing_method_offers_min_propellant() -> None:
    for name in EXISTING_METHODS:
        assert "min_propellant" not in METHODS[name].objectives


# ---------------------------------------------------------------- methods refuse what they lack


@pytest.mark.parametrize("name", EXISTING_METHODS)
def test_existing_methods_refuse_phases_and_propulsion(name: str) -> None:
    info = METHODS[name]
    assert (info.phases, info.propulsion) == (False, False)
    described = info.describe()
    assert (described["phases"], described["propulsion"]) == (False, False)

    def refusals(document: dict[str, Any]) -> dict[str, tuple[str, str]]:
        document["method"] = {"name": name}
        problem = ProblemDocument.model_validate(document)
        return {i.field: (i.code, i.message) for i in check_support(problem)}

    both = refusals(skip_entry())
    assert set(both) == {"phases", "vehicle.propulsion"}, both  # before the method's own checks
    for field, flag in (("phases", "phases"), ("vehicle.propulsion", "propulsion")):
        code, message = both[field]
        assert code == "unsupported_by_method"
        assert message.startswith(f"{name} {SINGLE_PHASE}; choose a method that handles {flag} (")
        assert message.endswith("see GET /v1/methods)")

    assert set(refusals(unpowered(skip_entry()))) == {"phases"}
    powered = skip_entry()
    del powered["phases"]
    powered["terminal"] = {"altitude_m": 30000}
    assert set(refusals(powered)) == {"vehicle.propulsion"}


def test_a_method_declaring_phases_gets_past_the_refusal(monkeypatch: pytest.MonkeyPatch) -> None:
    """The flags decide: a method that handles phases (but not propulsion) is refused only the
    propulsion, is named where the refusal suggests another method, and runs its own checks on an
    unpowered phased problem."""
    phased = dataclasses.replace(METHODS["hp-scp"], phases=True)
    monkeypatch.setitem(method_registry.METHODS, "hp-scp", phased)
    document = skip_entry()
    document["method"] = {"name": "hp-scp"}
    issues = {i.field: i.message for i in check_support(ProblemDocument.model_validate(document))}
    assert set(issues) == {"vehicle.propulsion"}
    assert issues["vehicle.propulsion"].startswith(
        "hp-scp solves phased or single-phase problems without propulsion; "
    )
    document["method"] = {"name": "energy-scp"}
    issues = {i.field: i.message for i in check_support(ProblemDocument.model_validate(document))}
    named = re.search(r"handles phases \((.*); see GET /v1/methods\)$", issues["phases"])
    assert named is not None and "hp-scp" in named.group(1).split(", "), issues["phases"]
    document = unpowered(skip_entry())
    document["method"] = {"name": "hp-scp"}
    issues = {i.field: i.message for i in check_support(ProblemDocument.model_validate(document))}
    assert "phases" not in issues


def test_methods_list_their_capabilities() -> None:
    for described in list_methods():
        assert isinstance(described["phases"], bool)
        assert isinstance(described["propulsion"], bool)


# ---------------------------------------------------------------- the service answers 422


@pytest.fixture
def client(tmp_path: Path) -> Iterator[TestClient]:
    settings = Settings(data_dir=tmp_path, database_url="", broker_url="")
    with TestClient(create_app(settings, RecordingDispatcher())) as test_client:
        yield test_client


@pytest.mark.parametrize("path", ["/v1/jobs", "/v1/problems/validate"])
def test_posting_a_phased_problem_to_an_existing_method_is_422_naming_phases(
    client: TestClient, path: str
) -> None:
    document = skip_entry()
    document["method"] = {"name": "foh-ptr"}
    error = assert_error(client.post(path, json=document), 422, "invalid_problem")
    issues = {i["field"]: i for i in error["issues"]}
    assert error["field"] == "phases"
    assert issues["phases"]["code"] == "unsupported_by_method"
    assert "foh-ptr " + SINGLE_PHASE in issues["phases"]["message"]
    assert "vehicle.propulsion" in issues
    assert client.get("/v1/jobs").json()["total"] == 0


def test_posting_a_broken_phase_is_422_naming_the_field(client: TestClient) -> None:
    document = skip_entry()
    document["phases"][1]["thrust_max_n"] = 2.5e6
    error = assert_error(client.post("/v1/jobs", json=document), 422, "invalid_problem")
    (issue,) = [i for i in error["issues"] if i["field"] == "phases[1].thrust_max_n"]
    assert issue["code"] == "thrust_limit"
