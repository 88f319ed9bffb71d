"""Looking at a result: the trajectory CSV, the plots, the zone outlines and the propagated
flight the verification keeps for them.

The CSV and plot tests read small hand-made result documents (pure logic); the last test solves
a built-in scenario with an active no-fly zone and checks the propagated columns against the
verification's own peaks.
"""

from __future__ import annotations

import copy
import csv
import io
import json
import math
import struct
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.report import available_plots, render_plot, trajectory_csv
from app.report.files import plot_command, read_result
from app.report.plots import (
    DPI,
    FIGURE_SIZE_IN,
    UnknownPlotError,
    figure,
    run_boundaries,
    zone_outline,
)
from app.report.table import NoTrajectoryError
from worker.solver.scenarios import get_scenario
from worker.solver.verification import MAX_PATH_SAMPLES, sample_rows


def _result(zone: dict[str, Any] | None = None) -> dict[str, Any]:
    """A small succeeded result: 5 nodes flying north along longitude 0, its propagated flight
    (the same curve, 4 samples between nodes) and a 3-record history."""
    t = np.linspace(0.0, 400.0, 5)
    lat = np.linspace(0.0, 20.0, 5)
    trajectory = {
        "time_s": t.tolist(),
        "altitude_m": np.linspace(80e3, 30e3, 5).tolist(),
        "longitude_deg": [0.0] * 5,
        "latitude_deg": lat.tolist(),
        "velocity_m_s": np.linspace(7000.0, 1000.0, 5).tolist(),
        "flight_path_angle_deg": [-1.0, -0.5, -0.2, -1.0, -5.0],
        "heading_deg": [0.0] * 5,
        "bank_deg": [10.0, -20.0, 30.0, None, 0.1],
        "alpha_deg": [40.0] * 5,
        "dynamic_pressure_Pa": [100.0, 5e3, 1.2e4, 1.5e4, 1.1e4],
        "load_factor_g": [0.1, 1.0, 1.5, 1.8, 1.2],
        "units": {"time_s": "s", "altitude_m": "m", "latitude_deg": "deg", "bank_deg": "deg"},
        "nodes": 5,
    }
    fine = np.linspace(0.0, 400.0, 17)
    propagated = {
        name: np.interp(fine, t, np.nan_to_num(np.array(values, dtype=float))).tolist()
        for name, values in trajectory.items()
        if isinstance(values, list)
    }
    propagated["samples"] = fine.size
    zones = [] if zone is None else [zone]
    history = [
        {
            "iteration": i,
            "cost": 10.0 - i,
            "objective_value": 10.0 - i,
            "max_state_change": {"altitude_m": 10.0**-i, "velocity_m_s": 2.0 * 10.0**-i},
            "virtual_control_norm": 10.0**-4 * i,
            "extra": {"weight_trust_region": 0.1 / i, "start": 1 if i < 3 else 2},
        }
        for i in (1, 2, 3)
    ]
    return {
        "status": "succeeded",
        "method": "foh-ptr",
        "trajectory": trajectory,
        "verification": {
            "feasible": True,
            "path_maxima": {"load_factor_g": {"max": 1.8, "limit": 2.5, "ratio": 0.72}},
            "control_limits": {"bank_deg": {"max": 30.0, "limit": 80.0}},
            "no_fly_zones": zones,
            "propagated": propagated,
        },
        "history": history,
    }


ZONE = {
    "name": "zone",
    "latitude_deg": 10.0,
    "longitude_deg": 4.0,
    "radius_deg": 2.0,
    "metric": "great_circle",
    "min_clearance_deg": 1.9,
    "within": True,
}


def test_csv_has_a_row_per_node_unit_headers_and_the_exact_numbers() -> None:
    result = _result()
    rows = list(csv.reader(io.StringIO(trajectory_csv(result))))
    header, body = rows[0], rows[1:]
    traj = result["trajectory"]
    names = [k for k, v in traj.items() if isinstance(v, list)]
    assert header[:3] == ["time_s [s]", "altitude_m [m]", "longitude_deg"]  # no unit: bare name
    assert [h.split(" [")[0] for h in header] == names
    assert len(body) == traj["nodes"]
    for j, name in enumerate(names):
        for i, cell in enumerate(row[j] for row in body):
            expected = traj[name][i]
            assert (cell == "") if expected is None else (float(cell) == expected)  # exact


def test_csv_of_a_result_without_trajectory_is_refused() -> None:
    with pytest.raises(NoTrajectoryError):
        trajectory_csv({"status": "failed", "history": []})


@pytest.mark.parametrize("metric", ["great_circle", "lat_lon"])
def test_zone_outline_is_at_the_radius_from_the_centre(metric: str) -> None:
    zone = {**ZONE, "latitude_deg": 55.0, "radius_deg": 7.5, "metric": metric}
    lon, lat = (np.radians(a) for a in zone_outline(zone))
    lat0, lon0 = math.radians(zone["latitude_deg"]), math.radians(zone["longitude_deg"])
    if metric == "great_circle":  # haversine central angle
        a = (
            np.sin((lat - lat0) / 2) ** 2
            + np.cos(lat) * math.cos(lat0) * np.sin((lon - lon0) / 2) ** 2
        )
        distance = 2.0 * np.arcsin(np.sqrt(a))
    else:
        distance = np.hypot(lat - lat0, lon - lon0)
    # round-off of the destination-point formula: far below a pixel of any plot
    assert np.max(np.abs(distance - math.radians(7.5))) < 1e-12


def test_sample_rows_thin_evenly_and_keep_the_last_row_and_every_peak() -> None:
    count = 8021  # a 401-node flight at 20 samples per interval
    rng = np.random.default_rng(3)
    peaks = [rng.random(count) for _ in range(3)]
    rows = sample_rows(count, peaks)
    assert rows[0] == 0 and rows[-1] == count - 1
    assert all(int(np.argmax(p)) in rows for p in peaks)
    stride = math.ceil(count / MAX_PATH_SAMPLES)
    assert count // stride <= rows.size <= MAX_PATH_SAMPLES + len(peaks) + 1
    assert np.all(np.diff(rows) > 0)
    assert sample_rows(50, [np.arange(50.0)]).tolist() == list(range(50))  # small: every row


def test_available_plots_follow_the_data() -> None:
    result = _result()
    names = available_plots(result)
    assert names[:4] == ["altitude-velocity", "ground-track", "states", "controls"]
    assert "heat-rate" not in names  # no heat model: no heat-rate column
    assert {"dynamic-pressure", "load-factor", "convergence"} <= set(names)
    assert available_plots({"status": "failed", "history": result["history"]}) == ["convergence"]
    assert available_plots({"status": "failed"}) == []
    with pytest.raises(UnknownPlotError):
        figure(result, "heat-rate")


def _png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    width, height = struct.unpack(">II", data[16:24])
    return width, height


def test_every_plot_renders_as_png_and_svg() -> None:
    result = _result(ZONE)
    size = (round(FIGURE_SIZE_IN[0] * DPI), round(FIGURE_SIZE_IN[1] * DPI))
    for name in available_plots(result):
        png = render_plot(result, name, "png")
        assert _png_size(png) == size, name
        svg = render_plot(result, name, "svg")
        assert ET.fromstring(svg).tag.endswith("svg"), name
        assert render_plot(result, name, "svg") == svg  # no date: same result, same bytes
    with pytest.raises(ValueError, match="format"):
        render_plot(result, "states", "jpg")


def _pixel(result: dict[str, Any], lon: float, lat: float) -> np.ndarray:
    """The RGB colour of the ground-track plot at a map point."""
    fig = figure(result, "ground-track")
    fig.canvas.draw()
    ax = fig.axes[0]
    x, y = ax.transData.transform((lon, lat))
    rgba = np.asarray(fig.canvas.buffer_rgba())  # type: ignore[attr-defined]
    row = rgba.shape[0] - round(y)  # display y grows upwards, image rows downwards
    return rgba[row, round(x), :3].astype(int)


def test_ground_track_draws_the_zone_filled_at_its_place() -> None:
    inside = _pixel(_result(ZONE), ZONE["longitude_deg"], ZONE["latitude_deg"])
    # the zone's fill: its red at alpha 0.35 over white
    assert inside[0] > 230 and 160 < inside[1] < 200 and 160 < inside[2] < 200, inside
    without = _pixel(_result(), ZONE["longitude_deg"], ZONE["latitude_deg"])
    assert without.tolist() == [255, 255, 255]


def test_plot_command_writes_each_plot_and_refuses_bad_input(tmp_path: Path) -> None:
    source = tmp_path / "result.json"
    source.write_text(json.dumps(_result(ZONE)))
    out = tmp_path / "plots"
    assert plot_command(str(source), str(out), ["png", "svg"], ["states", "convergence"]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "convergence.png",
        "convergence.svg",
        "states.png",
        "states.svg",
    ]
    with pytest.raises(ValueError, match="no plot heat-rate"):
        plot_command(str(source), str(out), ["png"], ["heat-rate"])
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(ValueError, match="invalid JSON"):
        read_result(str(tmp_path / "bad.json"))
    (tmp_path / "other.json").write_text("[1, 2]")
    with pytest.raises(ValueError, match="not a result document"):
        read_result(str(tmp_path / "other.json"))
    with pytest.raises(ValueError, match="no such file"):
        read_result(str(tmp_path / "missing.json"))


@pytest.mark.slow
def test_the_propagated_flight_reaches_the_reported_peaks() -> None:
    from app.schemas import ProblemDocument
    from worker.solver.api import solve_problem
    from worker.solver.scenarios import get_scenario

    document = copy.deepcopy(get_scenario("rlv-max-terminal-velocity-active-nfz").problem)
    result = solve_problem(ProblemDocument.model_validate(document))
    verification = result["verification"]
    flown = verification["propagated"]
    rows = flown["samples"]
    assert all(len(v) == rows for k, v in flown.items() if isinstance(v, list))
    assert rows <= MAX_PATH_SAMPLES + 5
    assert flown["units"]["heat_rate_W_m2"] == "W/m^2"
    assert flown["time_s"][0] == result["trajectory"]["time_s"][0]
    assert flown["time_s"][-1] == pytest.approx(verification["final_state"]["time_s"], abs=1e-9)
    for name, peak in verification["path_maxima"].items():
        assert max(flown[name]) == peak["max"]  # the peak's row is kept: the same number
    assert (
        max(abs(b) for b in flown["bank_deg"]) == verification["control_limits"]["bank_deg"]["max"]
    )
    zone = verification["no_fly_zones"][0]
    assert zone["radius_deg"] > 0 and zone["metric"] in ("great_circle", "lat_lon")
    # the flown ground track's closest approach is the reported clearance: its row is kept
    lat0, lon0 = math.radians(zone["latitude_deg"]), math.radians(zone["longitude_deg"])
    lat, lon = np.radians(flown["latitude_deg"]), np.radians(flown["longitude_deg"])
    a = np.sin((lat - lat0) / 2) ** 2 + np.cos(lat) * math.cos(lat0) * np.sin((lon - lon0) / 2) ** 2
    closest = math.degrees(float(np.min(2.0 * np.arcsin(np.sqrt(a))))) - zone["radius_deg"]
    assert closest == pytest.approx(zone["min_clearance_deg"], abs=1e-9)


@pytest.mark.slow
def test_waypoints_are_checked_in_order_on_the_flown_path_and_drawn() -> None:
    from app.schemas import ProblemDocument
    from worker.solver.problem import build_problem
    from worker.solver.trajectory import OptimizedTrajectory
    from worker.solver.verification import verify

    document = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    problem = build_problem(ProblemDocument.model_validate(document))
    assert problem.final_time is not None
    t = np.linspace(0.0, problem.final_time, 41)
    flight = OptimizedTrajectory("time", t, np.tile(problem.y0, (41, 1)), t, np.full(41, 0.3))
    flown = verify(problem, flight)["propagated"]
    assert "waypoints" not in verify(problem, flight)  # none asked: no entry
    middle = len(flown["time_s"]) // 2
    on_path = {"lat": flown["latitude_deg"][middle], "lon": flown["longitude_deg"][middle]}
    document["waypoints"] = [
        {
            "latitude_deg": on_path["lat"],
            "longitude_deg": on_path["lon"],
            "radius_km": 20,
            "order": 0,
        },
        # the start of the flight, but visited second: after the first it is far behind
        {
            "latitude_deg": flown["latitude_deg"][2],
            "longitude_deg": flown["longitude_deg"][2],
            "radius_km": 20,
            "order": 1,
        },
    ]
    report = verify(build_problem(ProblemDocument.model_validate(document)), flight)
    first, second = report["waypoints"]
    assert first["within"] and first["closest_deg"] < 1e-2  # a sample of the path itself
    assert first["at_time_s"] == pytest.approx(flown["time_s"][middle], abs=1e-6)
    assert not second["within"] and second["closest_deg"] > 5.0
    assert report["feasible"] is False
    result = {
        **_result(),
        "verification": {**_result()["verification"], "waypoints": report["waypoints"]},
    }
    assert _png_size(render_plot(result, "ground-track", "png")) == (800, 500)


@pytest.mark.slow
def test_every_reported_time_counts_from_the_problems_initial_time() -> None:
    from app.schemas import ProblemDocument
    from worker.solver.api import solve_problem

    document = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    document["initial_state"]["time_s"] = 500.0
    document["final_time"]["value_s"] = 2100.0  # the same 1600 s flight, 500 s later
    document["method"] = {"name": "foh-ptr", "max_iterations": 3, "bank_sign_starts": False}
    result = solve_problem(ProblemDocument.model_validate(document))
    verification = result["verification"]
    times = verification["propagated"]["time_s"]
    assert times[0] == 500.0 and result["trajectory"]["time_s"][0] == 500.0
    peaks = [*verification["path_maxima"].values(), *verification["control_limits"].values()]
    for peak in peaks:
        assert times[0] <= peak["at_time_s"] <= times[-1]
        assert peak["at_time_s"] in times  # the peak's own row of the flown path


@pytest.mark.slow
def test_a_problem_without_a_heat_rate_limit_is_verified_and_kept() -> None:
    """No heating model: the propagated flight has no heat-rate column and its other peaks are
    kept (a KeyError once turned this into an unexpected error)."""
    from app.schemas import ProblemDocument
    from worker.solver.api import solve_problem
    from worker.solver.scenarios import get_scenario

    document = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    del document["path_constraints"]["heat_rate"]
    result = solve_problem(ProblemDocument.model_validate(document))
    assert result["status"] == "succeeded", result.get("failure")
    flown = result["verification"]["propagated"]
    assert "heat_rate_W_m2" not in flown and "heat_rate_W_m2" not in result["trajectory"]
    peak = result["verification"]["path_maxima"]["dynamic_pressure_Pa"]
    assert max(flown["dynamic_pressure_Pa"]) == peak["max"]


def test_the_convergence_plot_marks_where_a_start_or_an_attempt_begins() -> None:
    """A single run has no mark; another start of a run, or auto's next attempt, begins one."""
    single = [{"iteration": i, "extra": {}} for i in range(1, 5)]
    assert run_boundaries(single) == []
    starts = [{"extra": {"start": s}} for s in (1, 1, 2, 2)]
    assert run_boundaries(starts) == [3]
    attempts = [
        {"extra": {"auto_attempt": 1, "start": 1}},
        {"extra": {"auto_attempt": 1, "start": 2}},
        {"extra": {"auto_attempt": 2}},
        {"extra": {"auto_attempt": 2}},
    ]
    assert run_boundaries(attempts) == [2, 3]
