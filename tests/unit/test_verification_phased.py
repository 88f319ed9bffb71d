"""The verification of a flight in phases (paper 004): the method's controls flown through the
powered dynamics phase after phase, with each phase's own end conditions, limits and bounds.

The flights are made here, with known controls: Betts' Space Shuttle (the heat-limited built-in
scenario's vehicle, atmosphere and heat model) with a rocket of 250 kN and 300 s, gliding for
300 s (angle of attack 40 deg, bank turning linearly from 60 to 40 deg between the nodes) and
then burning at full thrust for 200 s (30 deg, bank -30 deg). Its nodes are the same dynamics
integrated tighter (DOP853, rtol 1e-12) than the verification does (rtol 1e-10), so the
verification must find them again up to its own integration error. No mocks: every number is
the propagation's.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from app.report import available_plots, render_plot
from app.schemas import ProblemDocument
from app.schemas.result import Trajectory, Verification, json_ready
from worker.solver.models.powered import G_STANDARD, PoweredModel, Thruster
from worker.solver.path_limits import PathLimits
from worker.solver.phased_problem import PhasedProblem, PhaseModel
from worker.solver.problem import EntryProblem, TerminalTarget, build_problem
from worker.solver.result import phased_node_violations, phased_trajectory_columns, validated
from worker.solver.scenarios import get_scenario
from worker.solver.trajectory import TIME_STATE_NAMES, PhasedTrajectory
from worker.solver.units import COLUMN_UNITS
from worker.solver.verification import MAX_PATH_SAMPLES, VerificationStoppedError
from worker.solver.verification_phased import propagate_phased, verify_phased

THRUST_N = 250e3
ISP_S = 300.0
GLIDE_S = 300.0
BURN_S = 200.0
GLIDE_NODES = 5  # every 75 s: the dynamic-pressure peak (t = 90 s) falls between two nodes
BURN_NODES = 9
LAG_S = 20.0


@dataclass
class LinearControls:
    """Controls linear in time between knots, per phase (``PhaseControls``): columns alpha
    (rad), bank (rad) and, with propulsion, the commanded thrust (m0 g0)."""

    knots: list[np.ndarray]  # per phase, the knot times (nondimensional)
    values: list[np.ndarray]  # per phase, (len(knots), n_controls)

    def at(self, phase: int, t: np.ndarray) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        knots, values = self.knots[phase], self.values[phase]
        return np.stack([np.interp(t, knots, values[:, j]) for j in range(values.shape[1])], 1)

    def breaks(self, phase: int) -> np.ndarray:
        return self.knots[phase]


def _base() -> EntryProblem:
    problem = get_scenario("shuttle-max-crossrange-heat-limited").problem
    return build_problem(ProblemDocument.model_validate(problem))


BASE = _base()
SC = BASE.scales
TS = SC.time_s
M0 = BASE.forces.mass_kg
UNIT_N = M0 * SC.g0_m_s2  # newtons per nondimensional thrust (m0 g0)


def _free() -> dict[str, TerminalTarget]:
    return {name: TerminalTarget("free") for name in TIME_STATE_NAMES}


def _phase(name: str, start_s: float, end_s: float, **changes: Any) -> PhaseModel:
    fields: dict[str, Any] = {
        "name": name,
        "duration_min": (end_s - start_s) / TS,
        "duration_max": (end_s - start_s) / TS,
        "end": _free(),
        "end_si": _free(),
        "alpha_range": (0.0, math.radians(89.0)),
        "bank_range": (BASE.bank_min, BASE.bank_max),
        "thrust_max": THRUST_N / UNIT_N,
        "limits": PathLimits(heat=BASE.heat_model, heat_max_W_m2=BASE.limits.heat_max_W_m2),
    }
    fields.update(changes)
    return PhaseModel(**fields)


def _problem(lag_s: float | None = None) -> PhasedProblem:
    """The two phases: the glide with the scenario's bounds (bank in [-89, 1] deg, alpha in
    [0, 89] deg) and heat limit; the burn with a symmetric bank range, the whole [-90, 90] deg
    of alpha, no heat limit and a dynamic-pressure limit."""
    thruster = Thruster(
        max_thrust=THRUST_N / UNIT_N,
        flow=SC.g0_m_s2 * TS / (ISP_S * G_STANDARD),
        lag_rate=TS / lag_s if lag_s else None,
    )
    model = PoweredModel(forces=BASE.forces, omega=BASE.omega, thruster=thruster)
    glide = _phase("glide", 0.0, GLIDE_S, bank_range=(math.radians(-89), math.radians(61)))
    burn = _phase(
        "burn",
        GLIDE_S,
        GLIDE_S + BURN_S,
        alpha_range=(-0.5 * math.pi, 0.5 * math.pi),
        bank_range=(math.radians(-80), math.radians(80)),
        limits=PathLimits(heat=None, dynamic_pressure_max_Pa=5000.0, load_factor_max_g=4.0),
    )
    x0 = np.r_[BASE.y0, 1.0, 0.0] if thruster.lagged else np.r_[BASE.y0, 1.0]
    return PhasedProblem(base=BASE, model=model, phases=[glide, burn], x0=x0, mass_kg=M0)


def _controls(problem: PhasedProblem) -> LinearControls:
    t1, t2 = GLIDE_S / TS, (GLIDE_S + BURN_S) / TS
    glide_t = np.linspace(0.0, t1, GLIDE_NODES)
    glide = np.zeros((GLIDE_NODES, 3))
    glide[:, 0] = math.radians(40.0)
    glide[:, 1] = np.radians(np.linspace(60.0, 40.0, GLIDE_NODES))
    burn = np.array([[math.radians(30.0), math.radians(-30.0), THRUST_N / UNIT_N]] * 2)
    return LinearControls(knots=[glide_t, np.array([t1, t2])], values=[glide, burn])


def _flight(problem: PhasedProblem) -> PhasedTrajectory:
    """The nodes: the powered dynamics under the known controls, integrated tightly (DOP853,
    rtol 1e-12, atol 1e-14) piece by piece between the control knots, phase after phase."""
    controls = _controls(problem)
    t1, t2 = GLIDE_S / TS, (GLIDE_S + BURN_S) / TS
    bounds = [(0.0, t1), (t1, t2)]
    node_times = [np.linspace(0.0, t1, GLIDE_NODES), np.linspace(t1, t2, BURN_NODES)]
    x = np.asarray(problem.x0, dtype=float)
    ts, xs, us, phase = [], [], [], []
    for p, (start, end) in enumerate(bounds):
        knots = [k for k in controls.breaks(p) if start < k < end] + [end]
        pieces = []
        t_start = start
        for t_stop in knots:
            piece = solve_ivp(
                lambda t, y, p=p: problem.model.rates(y[None, :], controls.at(p, t))[0],
                (t_start, t_stop),
                x,
                method="DOP853",
                rtol=1e-12,
                atol=1e-14,
                dense_output=True,
            )
            pieces.append(piece)
            t_start, x = t_stop, piece.y[:, -1]
        for t in node_times[p]:
            piece = next(s for s in pieces if s.t[0] <= t <= s.t[-1] + 1e-15)
            xs.append(piece.sol(t) if t < piece.t[-1] else piece.y[:, -1])
        ts.append(node_times[p])
        us.append(controls.at(p, node_times[p]))
        phase.append(np.full(node_times[p].size, p))
    return PhasedTrajectory(
        t=np.concatenate(ts),
        x=np.array(xs),
        u=np.concatenate(us),
        phase=np.concatenate(phase),
        bounds=bounds,
        controls=controls,
    )


@pytest.fixture(scope="module")
def flown() -> tuple[PhasedProblem, PhasedTrajectory, dict[str, Any]]:
    problem = _problem()
    traj = _flight(problem)
    return problem, traj, verify_phased(problem, traj)


def _with_phase(problem: PhasedProblem, index: int, **changes: Any) -> PhasedProblem:
    phases = list(problem.phases)
    phases[index] = dataclasses.replace(phases[index], **changes)
    return dataclasses.replace(problem, phases=phases)


def _end_si(problem: PhasedProblem, traj: PhasedTrajectory, phase: int) -> dict[str, float]:
    """The optimized end of a phase (its last node) in SI units."""
    k = int(np.flatnonzero(traj.phase == phase)[-1])
    x = traj.x[k]
    return {
        "altitude_m": (x[0] - 1.0) * SC.radius_m,
        "velocity_m_s": x[3] * SC.speed_m_s,
        "flight_path_angle_deg": math.degrees(x[4]),
    }


def test_the_propagation_finds_the_nodes_again_and_the_report_is_a_verification(
    flown: tuple[PhasedProblem, PhasedTrajectory, dict[str, Any]],
) -> None:
    _, _, report = flown
    Verification.model_validate(json_ready(report))  # the result contract, every record typed
    assert report["reached_end"] and report["feasible"], report
    dev = report["max_deviation_along_path"]
    # two DOP853 integrations of the same flight, rtol 1e-10 (the verification's) and 1e-12:
    # their difference is the verification's integration error. The bounds are what rtol 1e-10
    # allows on each state's size: r ~ 1 (6.4e-4 m), V ~ 1 (7.9e-7 m/s), angles under 1.6 rad
    # (1e-8 deg), m ~ 1 (9e-6 kg); measured: 3e-6 m, 8e-9 m/s, 2e-10 deg, 1e-11 kg
    assert dev["altitude_m"] < 1e-3
    assert dev["velocity_m_s"] < 1e-6
    for name in ("longitude_deg", "latitude_deg", "flight_path_angle_deg", "heading_deg"):
        assert dev[name] < 1e-8, name
    assert dev["mass_kg"] < 1e-5
    assert report["final_state"]["time_s"] == pytest.approx(GLIDE_S + BURN_S, abs=1e-9)
    assert [p["name"] for p in report["phases"]] == ["glide", "burn"]
    glide, burn = report["phases"]
    assert glide["start_time_s"] == 0.0 and glide["end_time_s"] == pytest.approx(GLIDE_S)
    assert burn["start_time_s"] == glide["end_time_s"]
    assert glide["within"] and burn["within"] and glide["reached_end"] and burn["reached_end"]
    assert report["no_fly_zones"] == [] and report["heat_load_J_m2"] > 0.0
    units = report["propagated"]["units"]
    assert {"mass_kg", "thrust_n", "thrust_command_n", "phase"} <= set(units)


def test_the_state_flows_on_from_one_phase_into_the_next() -> None:
    problem = _problem()
    traj = _flight(problem)
    glide, burn = propagate_phased(problem, traj)
    # restarted where the control's pieces meet: the glide's bank is linear between its nodes
    assert len(glide.segments) == GLIDE_NODES - 1 and len(burn.segments) == 1
    assert [seg.t[0] * TS for seg in glide.segments] == pytest.approx([0.0, 75.0, 150.0, 225.0])
    assert np.array_equal(burn.x_start, glide.x_end)  # linkage: the very same state
    assert burn.start == glide.end == pytest.approx(GLIDE_S / TS, abs=0.0)
    # the burn's first dense sample is the glide's last (both phases' rows in the columns)
    np.testing.assert_array_equal(burn.sol(np.array([burn.start]))[0], glide.x_end)
    report = verify_phased(problem, traj)
    end = report["phases"][0]["end_state"]
    columns = report["propagated"]
    boundary = [i for i, t in enumerate(columns["time_s"]) if t == GLIDE_S]
    assert [columns["phase"][i] for i in boundary] == [0, 1]
    for name in ("altitude_m", "velocity_m_s", "mass_kg"):
        assert [columns[name][i] for i in boundary] == [end[name], end[name]], name
    # the controls jump there: the thrust is zero at the glide's last row, full at the burn's
    assert [columns["thrust_n"][i] for i in boundary] == [0.0, pytest.approx(THRUST_N)]


def test_the_mass_burns_at_the_rocket_equations_rate() -> None:
    problem = _problem()
    report = verify_phased(problem, _flight(problem))
    final = report["final_state"]["mass_kg"]
    glide_end = report["phases"][0]["end_state"]["mass_kg"]
    expected = M0 - THRUST_N * BURN_S / (ISP_S * G_STANDARD)  # m0 - T t / (Isp g_std)
    # dm/dt is constant during the burn: DOP853 integrates it exactly, only rounding is left
    # (a 92 t vehicle, 1e-12 relative, about 1e-7 kg)
    assert glide_end == pytest.approx(M0, abs=1e-7)
    assert final == pytest.approx(expected, abs=1e-6)
    assert M0 - final == pytest.approx(17_000.0, rel=0.01)  # 250 kN for 200 s at 300 s


def test_a_lagged_thrust_rises_to_its_command_and_burns_as_it_does() -> None:
    problem = _problem(lag_s=LAG_S)
    report = verify_phased(problem, _flight(problem))
    Verification.model_validate(json_ready(report))
    rise = 1.0 - math.exp(-BURN_S / LAG_S)
    final = report["final_state"]
    # T(t) = Tc (1 - exp(-t / tau)); m(t) = m0 - Tc / (Isp g_std) (t - tau (1 - exp(-t / tau)))
    assert final["thrust_n"] == pytest.approx(THRUST_N * rise, rel=1e-9)
    burnt = THRUST_N / (ISP_S * G_STANDARD) * (BURN_S - LAG_S * rise)
    assert final["mass_kg"] == pytest.approx(M0 - burnt, abs=1e-5)
    assert report["max_deviation_along_path"]["thrust_n"] < 1e-3
    assert report["phases"][1]["end_state"]["thrust_n"] == final["thrust_n"]


def test_end_conditions_report_the_exact_misses_of_shifted_targets() -> None:
    problem = _problem()
    traj = _flight(problem)
    glide_end, burn_end = _end_si(problem, traj, 0), _end_si(problem, traj, 1)
    ends = _free()
    ends["altitude_m"] = TerminalTarget("fixed", value=glide_end["altitude_m"] + 1000.0)
    lo = burn_end["velocity_m_s"] + 20.0
    last = _free()
    last["velocity_m_s"] = TerminalTarget("range", lo=lo, hi=lo + 30.0)
    last["flight_path_angle_deg"] = TerminalTarget(
        "soft", value=burn_end["flight_path_angle_deg"] - 2.0, weight=1.0
    )
    shifted = _with_phase(_with_phase(problem, 0, end_si=ends), 1, end_si=last)
    report = verify_phased(shifted, traj)
    Verification.model_validate(json_ready(report))
    glide, burn = report["phases"]
    # the propagated ends are the nodes' within the integration error (above: < 1e-3 m, 1e-6
    # m/s, 1e-8 deg), so the misses are the shifts
    miss = glide["end_error_vs_target"]["altitude_m"]
    assert miss["kind"] == "fixed" and miss["error"] == pytest.approx(-1000.0, abs=1e-2)
    assert not miss["within"] and not glide["within"]
    assert set(glide["end_error_vs_target"]) == {"altitude_m"}
    speed = burn["end_error_vs_target"]["velocity_m_s"]
    assert speed["kind"] == "range" and speed["error"] == pytest.approx(20.0, abs=1e-5)
    soft = burn["end_error_vs_target"]["flight_path_angle_deg"]
    assert soft["kind"] == "soft" and soft["error"] == pytest.approx(2.0, abs=1e-7)
    assert not soft["within"] and not burn["within"]  # the range decides, the soft is reported
    # the last phase's end is the terminal check, as in the single-phase report
    assert report["terminal_error_vs_target"] == burn["end_error_vs_target"]
    assert not report["feasible"] and report["reached_end"]

    soft_only = dict(last, velocity_m_s=TerminalTarget("free"))
    report = verify_phased(_with_phase(problem, 1, end_si=soft_only), traj)
    assert report["feasible"] and report["phases"][1]["within"]  # a soft miss only reported


def test_a_path_limit_exceeded_between_nodes_is_caught_with_its_phase() -> None:
    problem = _problem()
    traj = _flight(problem)
    columns = phased_trajectory_columns(problem, traj)
    pressure, phase = (np.array(columns[k]) for k in ("dynamic_pressure_Pa", "phase"))
    at_nodes = float(np.max(pressure[phase == 0]))
    limited = _with_phase(
        problem,
        0,
        limits=dataclasses.replace(problem.phases[0].limits, dynamic_pressure_max_Pa=at_nodes),
    )
    assert phased_node_violations(limited, traj) == []  # every node exactly at or under it
    report = verify_phased(limited, traj)
    peak = report["path_maxima"]["dynamic_pressure_Pa"]
    # the glide's peak (t = 90 s) lies between the nodes at 75 and 150 s, about 2 % above
    assert peak["phase"] == "glide" and peak["limit"] == at_nodes
    assert peak["ratio"] > 1.01 and not peak["within"] and not report["feasible"]
    assert 75.0 < peak["at_time_s"] < 150.0
    assert peak["ratio"] == pytest.approx(peak["max"] / at_nodes)
    Verification.model_validate(json_ready(report))


def test_each_path_peak_names_the_phase_whose_limit_binds() -> None:
    problem = _problem()
    traj = _flight(problem)
    report = verify_phased(problem, traj)
    load = report["path_maxima"]["load_factor_g"]
    flown = report["propagated"]
    assert flown["samples"] < MAX_PATH_SAMPLES  # every dense row kept: the burn's peak too
    factor, phase = (np.array(flown[k]) for k in ("load_factor_g", "phase"))
    # only the burn limits the load factor: its limit, its own peak over the limit
    assert load["phase"] == "burn" and load["limit"] == 4.0
    assert load["ratio"] == float(np.max(factor[phase == 1])) / 4.0
    # a tighter glide limit binds instead, though the burn's limit stays what it was
    tight = _with_phase(
        problem, 0, limits=dataclasses.replace(problem.phases[0].limits, load_factor_max_g=1.0)
    )
    load = verify_phased(tight, traj)["path_maxima"]["load_factor_g"]
    assert load["phase"] == "glide" and load["limit"] == 1.0 and load["ratio"] == load["max"]
    # limits in both phases: the peak is the whole flight's (the glide's 0.59 g), the limit the
    # one it comes closest to (the burn's 0.2 g, under about 0.11 g: above the glide's 0.15)
    both = _with_phase(
        problem, 0, limits=dataclasses.replace(problem.phases[0].limits, load_factor_max_g=4.0)
    )
    both = _with_phase(
        both, 1, limits=dataclasses.replace(problem.phases[1].limits, load_factor_max_g=0.2)
    )
    load = verify_phased(both, traj)["path_maxima"]["load_factor_g"]
    assert load["phase"] == "burn" and load["limit"] == 0.2
    assert load["ratio"] == float(np.max(factor[phase == 1])) / 0.2
    assert load["max"] == float(np.max(factor)) and load["max"] / 4.0 < load["ratio"] < 1.0
    # the heat rate: the glide's limit only, the burn heats too (the flight's heat model)
    heat = report["path_maxima"]["heat_rate_W_m2"]
    assert heat["phase"] == "glide" and heat["limit"] == BASE.limits.heat_max_W_m2


def test_control_bounds_are_read_per_phase_with_the_single_phase_ratios(
    flown: tuple[PhasedProblem, PhasedTrajectory, dict[str, Any]],
) -> None:
    _, _, report = flown
    limits = report["control_limits"]
    # alpha 40 deg in [0, 89] (glide), 30 deg in [-90, 90] (burn): the share of the half-width
    # used from the range's middle, the largest over both phases
    top = limits["alpha_max_deg"]
    assert top["phase"] == "burn" and top["limit"] == pytest.approx(90.0)
    assert top["ratio"] == pytest.approx(30.0 / 90.0) and top["max"] == pytest.approx(30.0)
    low = limits["alpha_min_deg"]
    assert low["phase"] == "glide" and low["limit"] == 0.0
    assert low["ratio"] == pytest.approx((40.0 - 44.5) / (0.0 - 44.5))
    # bank: glide [-89, 61] (asymmetric, middle -14), burn [-80, 80]; the largest bank is the
    # glide's 60 deg at its start, 74 / 75 of the upper half-width
    bank = limits["bank_deg"]
    assert bank["phase"] == "glide" and bank["max"] == pytest.approx(60.0)
    assert bank["ratio"] == pytest.approx(74.0 / 75.0) and bank["at_time_s"] == 0.0
    low_bank = limits["bank_min_deg"]  # the burn's -30 deg: 30 / 80 of its half-width
    assert low_bank["phase"] == "burn" and low_bank["ratio"] == pytest.approx(30.0 / 80.0)
    assert all(entry["within"] for entry in limits.values())


def test_columns_have_their_units_and_one_value_per_node(
    flown: tuple[PhasedProblem, PhasedTrajectory, dict[str, Any]],
) -> None:
    problem, traj, _ = flown
    columns = phased_trajectory_columns(problem, traj)
    Trajectory.model_validate(columns)
    names = [k for k, v in columns.items() if isinstance(v, list)]
    assert names == [
        "time_s",
        "altitude_m",
        "longitude_deg",
        "latitude_deg",
        "velocity_m_s",
        "flight_path_angle_deg",
        "heading_deg",
        "bank_deg",
        "alpha_deg",
        "heat_rate_W_m2",
        "dynamic_pressure_Pa",
        "load_factor_g",
        "mass_kg",
        "thrust_n",
        "thrust_command_n",
        "phase",
    ]
    assert columns["units"] == {name: COLUMN_UNITS[name] for name in names}
    assert columns["units"]["mass_kg"] == "kg" and columns["units"]["thrust_n"] == "N"
    assert all(len(columns[name]) == columns["nodes"] == traj.t.size for name in names)
    assert columns["phase"] == [0] * GLIDE_NODES + [1] * BURN_NODES
    assert columns["thrust_command_n"][-1] == pytest.approx(THRUST_N)
    assert columns["mass_kg"][0] == M0
    assert columns["time_s"][GLIDE_NODES - 1] == columns["time_s"][GLIDE_NODES] == GLIDE_S


def test_node_violations_name_the_phase_the_quantity_and_where() -> None:
    problem = _problem()
    traj = _flight(problem)
    glide_end = _end_si(problem, traj, 0)
    ends = _free()
    ends["altitude_m"] = TerminalTarget("fixed", value=glide_end["altitude_m"] + 1000.0)
    # the burn's dynamic pressure at its nodes is at most about 307 Pa (the glide's 1 650 Pa
    # is under the glide's own, absent, limit)
    burn_limits = dataclasses.replace(problem.phases[1].limits, dynamic_pressure_max_Pa=250.0)
    broken = _with_phase(_with_phase(problem, 0, end_si=ends), 1, limits=burn_limits)
    messages = phased_node_violations(broken, traj)
    assert len(messages) == 2, messages
    pressure, altitude = sorted(messages, key=lambda m: "altitude" in m)
    columns = phased_trajectory_columns(problem, traj)
    burn = np.flatnonzero(np.array(columns["phase"]) == 1)
    node = int(burn[np.argmax(np.array(columns["dynamic_pressure_Pa"])[burn])])
    ratio = columns["dynamic_pressure_Pa"][node] / 250.0
    assert 1.2 < ratio < 1.25
    t = columns["time_s"][node]
    assert pressure == (
        f"phase 1 (burn): dynamic pressure {ratio:.4f} of its limit at t = {t:.1f} s (node {node})"
    )
    assert altitude.startswith("phase 0 (glide): end altitude_m off by -1000 (tolerance 500)")
    assert altitude.endswith("at t = 300.0 s (node 4)")  # the glide's last node


def test_a_stop_request_ends_the_propagation() -> None:
    problem = _problem()
    traj = _flight(problem)
    asked = 0

    def should_stop() -> bool:
        nonlocal asked
        asked += 1
        return True

    with pytest.raises(VerificationStoppedError):
        verify_phased(problem, traj, should_stop=should_stop)
    assert asked == 1  # the first right-hand side asks, and stops


def test_a_flight_into_the_ground_ends_early_and_says_where() -> None:
    problem = _problem()
    traj = _flight(problem)
    x0 = np.array(problem.x0)
    # 1 km up at 300 m/s, diving at 80 deg: the drag and the banked lift slow and turn it, and
    # the ground ends the glide after about 7.5 s (at -46 deg)
    x0[0] = 1.0 + 1000.0 / SC.radius_m
    x0[3] = 300.0 / SC.speed_m_s
    x0[4] = math.radians(-80.0)
    report = verify_phased(dataclasses.replace(problem, x0=x0), traj)
    Verification.model_validate(json_ready(report))
    assert not report["reached_end"] and not report["feasible"]
    (glide,) = report["phases"]  # the burn was never flown
    assert not glide["reached_end"] and 2.0 < glide["end_time_s"] < 10.0
    assert glide["end_state"]["altitude_m"] == pytest.approx(0.0, abs=1e-6)
    assert report["final_state"]["time_s"] == glide["end_time_s"]


def test_every_plot_renders_for_a_phased_result(
    flown: tuple[PhasedProblem, PhasedTrajectory, dict[str, Any]],
) -> None:
    problem, traj, report = flown
    result = validated(
        {
            "status": "succeeded",
            "method": "phased",
            "trajectory": phased_trajectory_columns(problem, traj),
            "verification": report,
            "history": [  # a state change in one record only: no curve, no legend
                {"iteration": 1, "cost": 2.0, "max_state_change": {"altitude_m": 10.0}},
                {"iteration": 2, "cost": 1.0},
            ],
            "timing": {"wall_s": 1.0, "conic_solve_s": 0.0, "iterations": 2},
        }
    )
    names = available_plots(result)
    assert "mass-thrust" in names and {"heat-rate", "dynamic-pressure"} <= set(names)
    with warnings.catch_warnings():
        # no division by the repeated time at the hand-over, no empty legend
        warnings.simplefilter("error")
        for name in names:
            assert render_plot(result, name, "png")[:8] == b"\x89PNG\r\n\x1a\n", name
