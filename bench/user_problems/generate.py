"""A seeded generator of the problems users send: problem documents across the contract's envelope.

Each vehicle of the built-in scenarios (the RLV of papers 000/002 on its velocity schedule, the
Space Shuttle of Betts with an optimized angle of attack, the CAV-H parabolic polar of paper 001)
with its mass, area and lift varied; entry states and targets across the envelope (downrange
2 000-10 000 km, crossrange to +-1 500 km, any heading); no-fly zones on and off the direct path;
limits from loose to active (relative to the full-lift-up flight's peaks, ``liftup``); every
objective the vehicle supports; fixed and free final time; the exponential and U.S. 1976
atmospheres. Every ``INFEASIBLE_EVERY``-th problem is made infeasible on purpose, by one of three
causes with a physical argument: a heat limit below the lift-up peak, a no-fly zone covering the
target, or a downrange beyond what the entry speed can cover in the fixed final time.

A problem is named by its index and features and is a pure function of (seed, index).
"""

from __future__ import annotations

import copy
import json
import math
from importlib import resources
from typing import Any

import numpy as np

from bench.user_problems.liftup import lift_up_peaks, state_loads

SEED = 36
"""The committed suite's seed."""
INFEASIBLE_EVERY = 6
"""Every this many problems (index % INFEASIBLE_EVERY == 5) one is infeasible on purpose."""
EARTH_RADIUS_M = 6378000.0
REACH_FRACTION = 0.85
"""Targets lie within this fraction of the lift-up flight's ground range (the vehicle's reach
to first order), so that most problems are feasible; those made infeasible say why."""
SHORTEST_FACTOR = 1.1
"""Targets lie beyond this times the track of the flight banked at the bank limit all along
(the least a vehicle without lift down can fly, to first order)."""
FREE_TIME_MAX_S = 3000.0
"""Latest final time of a free final time: a bound the contract states, so that the reference
and the methods solve the same problem (a glide near orbital speed could otherwise go on)."""
MAX_PATH_LATITUDE_DEG = 70.0
"""Paths are kept off the poles (the longitude is not continuous there)."""

VEHICLES = {
    "rlv": "rlv-max-terminal-velocity",
    "shuttle": "shuttle-max-crossrange",
    "cavh": "cav-h-min-time",
}
"""Each vehicle and the built-in scenario it comes from."""
HEAT_MODELS = {
    "rlv": {"k_q": 9.4369e-5},
    "shuttle": None,  # the scenario's heat-limited variant: k_q and alpha factor of Betts
    "cavh": {"k_q": 9.4369e-5, "velocity_exponent": 3.0},
}
OBJECTIVES = ("max_terminal_velocity", "min_heat_load", "min_time", "max_final_extent")
INFEASIBLE_CAUSES = ("heat_below_lift_up", "terminal_dynamic_pressure", "downrange_beyond_speed")


def _scenario(name: str) -> dict[str, Any]:
    """A built-in scenario's problem document."""
    text = resources.files("worker.solver.scenarios").joinpath(f"{name}.json").read_text()
    return dict(json.loads(text)["problem"])


def destination(lat: float, lon: float, bearing: float, distance: float) -> tuple[float, float]:
    """The point ``distance`` (radians of arc) from (lat, lon) along ``bearing`` (all radians)."""
    lat2 = math.asin(
        math.sin(lat) * math.cos(distance) + math.cos(lat) * math.sin(distance) * math.cos(bearing)
    )
    lon2 = lon + math.atan2(
        math.sin(bearing) * math.sin(distance) * math.cos(lat),
        math.cos(distance) - math.sin(lat) * math.sin(lat2),
    )
    return lat2, lon2


def bearing_to(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Initial great-circle bearing from point 1 to point 2 (radians)."""
    dl = lon2 - lon1
    return math.atan2(
        math.sin(dl) * math.cos(lat2),
        math.cos(lat1) * math.sin(lat2) - math.sin(lat1) * math.cos(lat2) * math.cos(dl),
    )


def _vehicle(kind: str, rng: np.random.Generator) -> tuple[dict[str, Any], dict[str, Any]]:
    """The vehicle varied (mass, area, lift) and its heat model."""
    base = _scenario(VEHICLES[kind])
    vehicle = copy.deepcopy(base["vehicle"])
    vehicle["mass_kg"] = round(float(vehicle["mass_kg"]) * rng.uniform(0.8, 1.25), 1)
    vehicle["reference_area_m2"] = round(
        float(vehicle["reference_area_m2"]) * rng.uniform(0.85, 1.2), 3
    )
    aero = vehicle["aerodynamics"]
    lift = round(float(rng.uniform(0.92, 1.08)), 3)
    if aero["model"] == "parabolic_polar":
        aero["cl_star"] = round(float(aero["cl_star"]) * lift, 5)
        aero["lambda_max"] = 1.5
    else:
        aero["cl_coefficients"] = [round(c * lift, 7) for c in aero["cl_coefficients"]]
    if kind == "shuttle":
        vehicle["angle_of_attack"] = {"mode": "optimized", "min_deg": 0, "max_deg": 45}
        heat = dict(
            _scenario("shuttle-max-crossrange-heat-limited")["path_constraints"]["heat_rate"]
        )
        heat.pop("max_W_m2")
    else:
        heat = dict(HEAT_MODELS[kind] or {})
    return vehicle, heat


def _entry(kind: str, rng: np.random.Generator) -> dict[str, float]:
    """An entry state within the vehicle's envelope."""
    speed = {"rlv": (7000, 7450), "shuttle": (7200, 7700), "cavh": (6500, 7300)}[kind]
    return {
        "altitude_m": round(float(rng.uniform(95e3, 121e3)), -2),
        "longitude_deg": round(float(rng.uniform(-60, 60)), 2),
        "latitude_deg": round(float(rng.uniform(-30, 30)), 2),
        "velocity_m_s": round(float(rng.uniform(*speed)), 1),
        "flight_path_angle_deg": round(float(rng.uniform(-1.5, -0.2)), 2),
        "heading_deg": round(float(rng.uniform(-180, 180)), 1),
    }


def _path_latitudes(lat: float, lon: float, bearing: float, distance: float) -> float:
    """Largest |latitude| (deg) along the great circle from (lat, lon)."""
    return max(
        abs(math.degrees(destination(lat, lon, bearing, d)[0]))
        for d in np.linspace(0.0, distance, 25)
    )


def _target(
    entry: dict[str, float], rng: np.random.Generator, downrange_km: float
) -> tuple[float, float, float]:
    """Target (lat, lon in degrees) at the downrange along the heading and a crossrange to
    +-1 500 km; the crossrange (km) too."""
    lat0, lon0 = math.radians(entry["latitude_deg"]), math.radians(entry["longitude_deg"])
    heading = math.radians(entry["heading_deg"])
    cross_km = float(rng.uniform(-1500, 1500))
    lat1, lon1 = destination(lat0, lon0, heading, downrange_km * 1e3 / EARTH_RADIUS_M)
    back = bearing_to(lat1, lon1, lat0, lon0)
    lat2, lon2 = destination(
        lat1, lon1, back + math.pi + math.pi / 2, cross_km * 1e3 / EARTH_RADIUS_M
    )
    return math.degrees(lat2), math.degrees(lon2), cross_km


def generate(index: int, seed: int = SEED) -> dict[str, Any]:
    """Problem ``index`` of the suite of ``seed``: {name, features, problem}."""
    rng = np.random.default_rng([seed, index])
    kind = ("rlv", "shuttle", "cavh")[index % 3]
    objective = OBJECTIVES[(index // 3) % len(OBJECTIVES)]
    infeasible = (
        INFEASIBLE_CAUSES[(index // INFEASIBLE_EVERY) % 3]
        if index % INFEASIBLE_EVERY == 5
        else None
    )
    if infeasible == "heat_below_lift_up":
        kind = "rlv"  # a scheduled angle of attack: the lift-up flight is the coolest
    if infeasible == "downrange_beyond_speed" and objective in ("min_time", "max_final_extent"):
        objective = "max_terminal_velocity"  # needs a fixed final time
    vehicle, heat = _vehicle(kind, rng)
    atmosphere: dict[str, Any] = (
        {"model": "us76"}
        if rng.uniform() < 0.35
        else {"model": "exponential", "density_sea_level_kg_m3": 1.225, "scale_height_m": 7200}
    )
    h_end = round(float(rng.uniform(25e3, 32e3)), -2)
    planet = {"radius_m": EARTH_RADIUS_M, "g0_m_s2": 9.81, "atmosphere": atmosphere}
    bank_max = float(rng.choice([60.0, 70.0, 80.0]))
    for _ in range(100):  # an entry and target whose path stays off the poles
        entry = _entry(kind, rng)
        peaks = lift_up_peaks(
            {
                "vehicle": vehicle,
                "planet": planet,
                "initial_state": entry,
                "terminal": {"altitude_m": h_end},
                "path_constraints": {"heat_rate": heat},
            }
        )
        banked = lift_up_peaks(
            {
                "vehicle": vehicle,
                "planet": planet,
                "initial_state": entry,
                "terminal": {"altitude_m": h_end},
            },
            bank_deg=bank_max,
        )
        reach = min(10000.0, REACH_FRACTION * peaks["range_at_end_km"])
        shortest = max(2000.0, SHORTEST_FACTOR * banked["range_at_end_km"])
        if reach < shortest + 300.0:  # no window between the two flights: another entry
            continue
        downrange = float(rng.uniform(shortest, reach))
        t_lat, t_lon, cross = _target(entry, rng, downrange)
        lat0, lon0 = math.radians(entry["latitude_deg"]), math.radians(entry["longitude_deg"])
        distance = (
            math.degrees(
                math.acos(
                    min(
                        1.0,
                        math.sin(lat0) * math.sin(math.radians(t_lat))
                        + math.cos(lat0)
                        * math.cos(math.radians(t_lat))
                        * math.cos(math.radians(t_lon) - lon0),
                    )
                )
            )
            * (math.pi / 180.0)
            * EARTH_RADIUS_M
            / 1e3
        )
        if not shortest <= distance <= reach:
            continue
        lat0, lon0 = math.radians(entry["latitude_deg"]), math.radians(entry["longitude_deg"])
        bearing = bearing_to(lat0, lon0, math.radians(t_lat), math.radians(t_lon))
        arc = downrange * 1e3 / EARTH_RADIUS_M
        if (
            _path_latitudes(lat0, lon0, bearing, arc) < MAX_PATH_LATITUDE_DEG
            and abs(t_lon) < 179.0
            and abs(math.radians(entry["longitude_deg"]) - math.radians(t_lon)) < math.pi
        ):
            break
    rotation = bool(rng.uniform() < 0.5)
    features = [f"{index:03d}", kind, objective, atmosphere["model"]]
    doc: dict[str, Any] = {
        "name": "",
        "vehicle": vehicle,
        "planet": {
            "radius_m": EARTH_RADIUS_M,
            "g0_m_s2": 9.81,
            "rotation": rotation,
            "atmosphere": atmosphere,
        },
        "initial_state": entry,
        "control_limits": {"bank_max_deg": bank_max},
    }
    if kind == "rlv" and rng.uniform() < 0.4:
        doc["control_limits"]["bank_rate_max_deg_s"] = 10.0
        features.append("bank-rate")
    terminal: dict[str, Any] = {"altitude_m": h_end}
    # a fixed final time near the lift-up flight's, shorter for a shorter downrange
    natural_tf = round(peaks["time_at_end_s"] * math.sqrt(downrange / peaks["range_at_end_km"]), -1)
    target = {"latitude_deg": round(t_lat, 3), "longitude_deg": round(t_lon, 3)}
    fixed_tf: float | None = None
    if objective == "max_terminal_velocity":
        terminal |= target
        terminal["flight_path_angle_deg"] = {"kind": "range", "lo": -15.0, "hi": 0.0}
        if rng.uniform() < 0.5 or infeasible == "downrange_beyond_speed":
            fixed_tf = natural_tf
    elif objective == "min_heat_load":
        terminal |= target
        terminal["velocity_m_s"] = round(float(rng.uniform(700, 1100)), -1)
        terminal["flight_path_angle_deg"] = {"kind": "range", "lo": -15.0, "hi": 0.0}
        if rng.uniform() < 0.3:
            fixed_tf = natural_tf
    elif objective == "min_time":
        terminal |= target
        terminal["velocity_m_s"] = {"kind": "range", "lo": 700.0, "hi": 1500.0}
        terminal["flight_path_angle_deg"] = {"kind": "range", "lo": -15.0, "hi": 0.0}
    else:  # the farthest final position the heading points to most: latitude or longitude
        heading = math.radians(entry["heading_deg"])
        north, east = math.cos(heading), math.sin(heading)
        objective = (
            ("max" if north > 0 else "min") + "_final_latitude"
            if abs(north) > abs(east)
            else ("max" if east > 0 else "min") + "_final_longitude"
        )
        features[2] = objective
        terminal["velocity_m_s"] = round(float(rng.uniform(700, 1100)), -1)
        terminal["flight_path_angle_deg"] = {"kind": "range", "lo": -15.0, "hi": 0.0}
    doc["terminal"] = terminal
    doc["objective"] = objective
    doc["final_time"] = (
        {"kind": "fixed", "value_s": fixed_tf}
        if fixed_tf is not None
        else {"kind": "free", "max_s": FREE_TIME_MAX_S}
    )
    features.append("fixed-tf" if fixed_tf is not None else "free-tf")
    tight = rng.uniform() < 0.5
    v_end = terminal.get("velocity_m_s")
    q_end, n_end = state_loads(doc, h_end, float(v_end)) if isinstance(v_end, float) else (0.0, 0.0)
    limits = {
        "heat_rate": {
            **heat,
            "max_W_m2": round(peaks["heat_rate"] * (rng.uniform(1.1, 1.3) if tight else 3.0), -3),
        },
        "dynamic_pressure": {
            "max_Pa": round(
                max(peaks["dynamic_pressure"] * (1.3 if tight else 4.0), 8e3, 1.5 * q_end), -2
            )
        },
        "load_factor": {
            "max_g": round(max(peaks["load_factor"] * (1.3 if tight else 3.0), 2.0, 1.5 * n_end), 2)
        },
    }
    features.append("active-limits" if tight else "loose-limits")
    zone_kind = ("none", "on-path", "off-path")[int(rng.integers(0, 3))]
    if zone_kind != "none" and "latitude_deg" in terminal:
        lat0, lon0 = math.radians(entry["latitude_deg"]), math.radians(entry["longitude_deg"])
        lat1, lon1 = math.radians(t_lat), math.radians(t_lon)
        arc = downrange * 1e3 / EARTH_RADIUS_M
        mid = destination(
            lat0, lon0, bearing_to(lat0, lon0, lat1, lon1), arc * rng.uniform(0.4, 0.6)
        )
        if zone_kind == "off-path":
            side = bearing_to(lat0, lon0, lat1, lon1) + math.pi / 2 * rng.choice([-1, 1])
            mid = destination(mid[0], mid[1], side, math.radians(12.0))
        doc["no_fly_zones"] = [
            {
                "name": zone_kind,
                "center_latitude_deg": round(math.degrees(mid[0]), 3),
                "center_longitude_deg": round(math.degrees(mid[1]), 3),
                "radius_deg": round(float(rng.uniform(1.0, 2.5)), 2),
            }
        ]
        features.append(f"zone-{zone_kind}")
    argument = None
    if infeasible == "heat_below_lift_up":
        limits["heat_rate"]["max_W_m2"] = round(0.6 * peaks["heat_rate"], -3)
        argument = (
            f"the full-lift-up flight's heat-rate peak {peaks['heat_rate']:.4g} W/m^2 is "
            f"{1 / 0.6:.2f} times the limit; lift up keeps the vehicle highest for its speed"
        )
    elif infeasible == "terminal_dynamic_pressure":
        v_end = (
            float(terminal.get("velocity_m_s", 0.0))
            if not isinstance(terminal.get("velocity_m_s"), dict)
            else 0.0
        )
        if v_end <= 0.0:
            v_end = 900.0
            terminal["velocity_m_s"] = v_end
        rho_end = 1.225 * math.exp(-h_end / 7200.0)
        if atmosphere["model"] == "us76":
            from bench.nlp_models import us76_log_density

            z, log_rho = us76_log_density()
            rho_end = math.exp(float(np.interp(h_end, z, log_rho)))
        q_end = 0.5 * rho_end * v_end**2
        limits["dynamic_pressure"]["max_Pa"] = round(0.7 * q_end, -1)
        argument = (
            f"the terminal state itself ({h_end:.0f} m, {v_end:.0f} m/s) has a dynamic pressure "
            f"of {q_end:.0f} Pa, above the limit {0.7 * q_end:.0f} Pa"
        )
    elif infeasible == "downrange_beyond_speed":
        v_max = math.sqrt(entry["velocity_m_s"] ** 2 + 2 * 9.81 * entry["altitude_m"])
        fixed_tf = round(0.8 * downrange * 1e3 / v_max, -1)
        doc["final_time"] = {"kind": "fixed", "value_s": fixed_tf}
        argument = (
            f"the target is {downrange:.0f} km downrange, {downrange * 1e3 / fixed_tf:.0f} m/s "
            f"over the fixed {fixed_tf:.0f} s, above the largest speed {v_max:.0f} m/s the "
            "entry's energy allows"
        )
    doc["path_constraints"] = limits
    if infeasible is not None:
        features.append(f"infeasible-{infeasible}")
    tf_kind = "fixed-tf" if "value_s" in doc["final_time"] else "free-tf"
    features = [tf_kind if f in ("fixed-tf", "free-tf") else f for f in features]
    name = "-".join(features)
    doc["name"] = name
    return {
        "name": name,
        "seed": seed,
        "index": index,
        "features": {
            "vehicle": kind,
            "objective": objective,
            "atmosphere": atmosphere["model"],
            "rotation": rotation,
            "final_time": "fixed" if "value_s" in doc["final_time"] else "free",
            "limits": "active" if tight else "loose",
            "zone": zone_kind if doc.get("no_fly_zones") else "none",
            "downrange_km": round(downrange, 1),
            "crossrange_km": round(cross, 1),
            "infeasible_on_purpose": infeasible,
            "infeasibility_argument": argument,
            "lift_up_peaks": {k: round(float(v), 3) for k, v in peaks.items()},
        },
        "problem": doc,
    }
