"""Plausibility warnings (``app.schemas.plausibility``) and how a failed result uses them
(``worker.solver.diagnosis``): legal values far outside what entry vehicles fly are named,
never refused, and a failure names them before its other advice."""

from __future__ import annotations

import copy
import math
from typing import Any

import pytest

from app.schemas import ProblemDocument
from app.schemas.plausibility import (
    BALLISTIC_COEFFICIENT_KG_M2,
    PlausibilityWarning,
    drag_coefficient,
    entry_speed_max_m_s,
    plausibility_warnings,
    representative_alpha_deg,
)
from app.submission import apply_overrides
from worker.solver.diagnosis import blame_input, input_advice
from worker.solver.scenarios import get_scenario, list_scenarios

FOH = "rlv-max-terminal-velocity"


def _doc(scenario: str = FOH, **overrides: Any) -> ProblemDocument:
    return ProblemDocument.model_validate(
        apply_overrides(get_scenario(scenario).problem, overrides)
    )


def _fields(doc: ProblemDocument) -> list[str]:
    return [w.field for w in plausibility_warnings(doc)]


@pytest.mark.parametrize("scenario", [s.name for s in list_scenarios()])
def test_no_built_in_problem_is_implausible(scenario: str) -> None:
    assert plausibility_warnings(_doc(scenario)) == []


def test_an_entry_speed_in_km_s_is_named_with_its_likely_slip() -> None:
    (warning,) = plausibility_warnings(_doc(initial_state={"velocity_m_s": 7.3}))
    assert warning.field == "initial_state.velocity_m_s"
    assert (warning.value, warning.unit, warning.plausible_min) == (7.3, "m/s", 1000.0)
    assert warning.plausible_max == 13_100.0  # escape speed from 100 km and 7 km/s beyond
    assert warning.message.endswith("was it given in km/s?")


def test_the_fastest_plausible_entry_follows_the_planet() -> None:
    escape_sq = 2 * 9.81 * 6_378_000**2 / (6_378_000 + 100_000)  # from the entry at 100 km
    assert entry_speed_max_m_s(_doc()) == pytest.approx(math.sqrt(escape_sq + 7000**2))
    mars = {"radius_m": 3_396_200, "g0_m_s2": 3.71}
    assert _fields(_doc(planet=mars, initial_state={"velocity_m_s": 7_260})) == []  # Pathfinder
    assert _fields(_doc(initial_state={"velocity_m_s": 16_000})) == ["initial_state.velocity_m_s"]


def test_a_mass_in_tonnes_shows_in_the_ballistic_coefficient() -> None:
    doc = _doc(vehicle={"mass_kg": 104.305})  # 104 kg is a plausible mass on its own
    (warning,) = plausibility_warnings(doc)
    assert warning.field == "vehicle"
    assert warning.value == pytest.approx(104.305 / (0.9616023 * 391.22), rel=1e-6)
    assert (warning.plausible_min, warning.plausible_max) == BALLISTIC_COEFFICIENT_KG_M2
    assert "vehicle.mass_kg 104.3 kg" in warning.message
    assert warning.message.endswith("is the mass in tonnes?")


def test_the_drag_of_each_model_is_read_at_the_hypersonic_attitude() -> None:
    rlv, shuttle, cav = _doc(), _doc("shuttle-max-crossrange"), _doc("cav-h-min-time")
    assert representative_alpha_deg(rlv) == 40.0  # the schedule's top
    assert representative_alpha_deg(shuttle) == 40.0  # optimized in [0, 89]: 40 deg
    assert representative_alpha_deg(cav) is None  # a polar has no attitude
    assert drag_coefficient(cav.vehicle.aerodynamics, None) == (
        pytest.approx(0.0646 + 0.3606277 * 0.42324**2),
        "at its design lift (lambda 1)",
    )
    table = {
        "model": "table",
        "alpha_deg": [0, 20, 60],
        "mach": [2, 20],
        "cl": [[0, 0], [0.5, 0.4], [1.0, 0.9]],
        "cd": [[0.1, 0.05], [0.3, 0.25], [1.1, 1.05]],
    }
    cd, where = drag_coefficient(_doc(vehicle={"aerodynamics": table}).vehicle.aerodynamics, 40.0)
    assert cd == pytest.approx(0.65) and where == "at alpha 40 deg, Mach 20"


def test_limits_in_the_wrong_units_are_each_named() -> None:
    limits = {
        "heat_rate": {"max_W_m2": 1500},  # kW/m^2
        "dynamic_pressure": {"max_Pa": 18},  # kPa
        "load_factor": {"max_g": 0.25},
    }
    warnings = plausibility_warnings(_doc(path_constraints=limits))
    assert [w.field for w in warnings] == [
        "path_constraints.heat_rate.max_W_m2",
        "path_constraints.dynamic_pressure.max_Pa",
        "path_constraints.load_factor.max_g",
    ]
    assert warnings[0].message.endswith("in kW/m^2?") and warnings[1].message.endswith("in kPa?")


def test_a_phase_limit_is_named_at_its_phase() -> None:
    doc = get_scenario("shuttle-skip-min-propellant").problem
    phases = copy.deepcopy(doc["phases"])
    phases[1]["path_constraints"] = {"dynamic_pressure": {"max_Pa": 5e7}}
    assert _fields(_doc("shuttle-skip-min-propellant", phases=phases)) == [
        "phases[1].path_constraints.dynamic_pressure.max_Pa"
    ]


def _warned(**overrides: Any) -> list[dict[str, Any]]:
    return [w.model_dump() for w in plausibility_warnings(_doc(**overrides))]


def test_a_start_that_failed_on_an_implausible_input_names_the_input() -> None:
    failure = {
        "code": "initial_guess",
        "message": "no constant-bank propagation of the sweep stays above the ground for the "
        "whole flight time; give method.initial_bank_deg",
    }
    blame_input(failure, _warned(initial_state={"velocity_m_s": 7.3}))
    assert failure["message"].startswith("no constant-bank propagation of the sweep stays")
    assert "initial_bank_deg" not in failure["message"]
    assert (
        "implausible input: initial_state.velocity_m_s: entry speed 7.3 m/s" in (failure["message"])
    )
    kept = {"code": "initial_guess", "message": "x; give method.initial_bank_deg"}
    blame_input(kept, [])  # nothing implausible: the method's own advice stands
    assert kept["message"] == "x; give method.initial_bank_deg"
    other = {"code": "infeasible", "message": "not converged; load factor 6.8 of its limit"}
    blame_input(other, _warned(vehicle={"mass_kg": 104.305}))
    assert other["message"] == "not converged; load factor 6.8 of its limit"


def test_the_advice_names_every_implausible_input() -> None:
    document = {"warnings": _warned(vehicle={"mass_kg": 104.305}, path_constraints={})}
    (hint,) = input_advice(document)
    assert hint.startswith("check the input first: vehicle: ballistic coefficient m/(CD S)")
    assert input_advice({"warnings": []}) == input_advice({}) == []


def test_a_warning_is_a_typed_record() -> None:
    (warning,) = plausibility_warnings(_doc(initial_state={"velocity_m_s": 7.3}))
    assert PlausibilityWarning.model_validate(warning.model_dump()) == warning
