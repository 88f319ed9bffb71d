"""Starting from an earlier answer: the guess contract, its interpolation onto a method's grid
(pure logic), and two methods started from a neighbouring problem's answer (real solves)."""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from app.schemas import ProblemDocument
from app.schemas.guess import GUESS_COLUMNS, GuessTrajectory
from worker.solver.guess_path import GuessPath
from worker.solver.problem import build_problem
from worker.solver.scenarios import get_scenario
from worker.solver.transcription.time_grid import guess_reference

COLUMNS = GUESS_COLUMNS


def test_a_guess_is_stretched_over_the_new_flight_time_and_interpolated_linearly() -> None:
    t = np.array([0.0, 1.0, 3.0])
    y = np.column_stack([t * k + 1.0 for k in range(6)])  # linear in time: exact
    guess = GuessPath(t=t, y=y, bank=2.0 * t)
    nodes = np.linspace(0.0, 6.0, 7)  # twice as long: the guess's t = nodes / 2
    states, bank = guess.on_times(nodes)
    np.testing.assert_allclose(states[:, 2], 2.0 * nodes / 2 + 1.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(bank, nodes, rtol=0, atol=1e-15)


def test_a_guess_in_energy_maps_its_energy_range_onto_the_grid() -> None:
    r = np.array([1.02, 1.01, 1.005])
    v = np.array([0.95, 0.6, 0.2])
    y = np.column_stack([r, [0.0, 0.1, 0.2], [0.0, 0.05, 0.1], v, [0.0, -0.01, -0.1], [0.0] * 3])
    guess = GuessPath(t=np.array([0.0, 1.0, 2.0]), y=y, bank=np.radians([10.0, 20.0, 30.0]))
    e = guess.energy()
    assert np.all(np.diff(e) > 0)  # a flight's energy variable e = 1/r - V^2/2 rises
    grid = np.linspace(e[0] - 0.01, e[-1] + 0.02, 5)  # another range: mapped end to end
    states, bank = guess.on_energies(grid)
    assert states[0, 0] == pytest.approx(r[0]) and states[-1, 0] == pytest.approx(r[-1])
    assert math.degrees(bank[0]) == pytest.approx(10.0) and math.degrees(bank[-1]) == pytest.approx(
        30.0
    )


def _columns(count: int = 3) -> dict[str, list[float]]:
    base = {name: [float(i) for i in range(count)] for name in COLUMNS}
    base["velocity_m_s"] = [7000.0 - i for i in range(count)]
    return base


@pytest.mark.parametrize(
    ("change", "where"),
    [
        ({"altitude_m": [1.0, 2.0]}, "altitude_m"),
        ({"time_s": [0.0, 2.0, 2.0]}, "time_s.2"),
        ({"velocity_m_s": [7000.0, 0.0, 10.0]}, "velocity_m_s.1"),
    ],
)
def test_a_bad_guess_trajectory_names_its_field(change: dict[str, Any], where: str) -> None:
    with pytest.raises(ValidationError) as raised:
        GuessTrajectory.model_validate({**_columns(), **change})
    locations = {".".join(str(p) for p in e["loc"]) for e in raised.value.errors()}
    assert where in locations, locations


def test_the_foh_reference_keeps_the_given_start_and_the_bank_limits() -> None:
    document = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    guess = _columns(5)
    guess["time_s"] = [0.0, 400.0, 800.0, 1200.0, 1600.0]
    guess["bank_deg"] = [0.0, 95.0, -95.0, 10.0, 0.0]  # beyond the 80 deg limit
    guess["altitude_m"] = [100e3, 80e3, 60e3, 40e3, 25e3]
    document["initial_guess"] = {"trajectory": guess}
    problem = build_problem(ProblemDocument.model_validate(document))
    reference = guess_reference(problem, 9)
    np.testing.assert_array_equal(reference.z[0, :6], problem.y0)
    assert np.max(np.abs(reference.z[:, 6])) <= problem.bank_max
    assert reference.s.sum() == pytest.approx(problem.final_time)
    assert problem.bank_rate_max is not None
    assert np.max(np.abs(reference.w)) <= problem.bank_rate_max


CASES = (
    ("rlv-max-terminal-velocity", ("path_constraints", "heat_rate", "max_W_m2"), 1.45e6),
    ("rlv-min-heat-load", ("vehicle", "mass_kg"), 100000.0),
)


@pytest.mark.slow
@pytest.mark.parametrize(("scenario", "path", "value"), CASES)
def test_a_neighbours_answer_saves_iterations_and_reaches_the_same_optimum(
    scenario: str, path: tuple[str, ...], value: float
) -> None:
    from worker.solver.api import solve_problem

    base = copy.deepcopy(get_scenario(scenario).problem)
    nominal = solve_problem(ProblemDocument.model_validate(base))
    variant = copy.deepcopy(base)
    node = variant
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    cold = solve_problem(ProblemDocument.model_validate(variant))
    trajectory = {name: nominal["trajectory"][name] for name in COLUMNS}
    warm = solve_problem(
        ProblemDocument.model_validate({**variant, "initial_guess": {"trajectory": trajectory}})
    )
    assert cold["status"] == warm["status"] == "succeeded"
    assert warm["provenance"]["initial_guess"].startswith("the given trajectory")
    # measured 36 -> 4 (foh-ptr) and 23 -> 13 (energy-scp) iterations
    assert warm["timing"]["iterations"] <= 0.75 * cold["timing"]["iterations"]
    # the same optimum to 0.1 %: two local solutions of one problem (measured 0.04 / 0.05 %)
    assert warm["objective"]["value"] == pytest.approx(cold["objective"]["value"], rel=1e-3)


def test_hp_scp_starts_from_a_guess_over_its_own_flight_time() -> None:
    from worker.solver.methods.hp_scp.method import HpScp

    document = copy.deepcopy(get_scenario("rlv-min-time-hp").problem)
    guess = _columns(4)
    guess["time_s"] = [0.0, 400.0, 900.0, 1330.0]
    guess["altitude_m"] = [80e3, 60e3, 40e3, 25e3]
    guess["bank_deg"] = [10.0, 50.0, 95.0, 20.0]  # beyond the bank range at one point
    guess["alpha_deg"] = [30.0, 45.0, 20.0, 10.0]  # beyond the alpha range at one point
    document["initial_guess"] = {"trajectory": guess}
    problem = build_problem(ProblemDocument.model_validate(document))
    method = HpScp(problem, ProblemDocument.model_validate(document).method)  # type: ignore[arg-type]
    reference = method.start()
    assert reference.tf * problem.scales.time_s == pytest.approx(1330.0)
    np.testing.assert_array_equal(reference.z[0, :6], problem.y0)
    assert problem.alpha_range is not None
    assert reference.z[:, 7].min() >= problem.alpha_range[0]
    assert reference.z[:, 7].max() <= problem.alpha_range[1]
    assert reference.z[:, 6].max() <= problem.bank_max
