"""Example problem documents of the contract (shown in the OpenAPI schema and the docs)."""

from __future__ import annotations

from typing import Any, Final

RLV_MIN_HEAT_LOAD: Final[dict[str, Any]] = {
    "name": "rlv-min-heat-load",
    "vehicle": {
        "mass_kg": 105000,
        "reference_area_m2": 300,
        "aerodynamics": {
            "model": "polynomial",
            "cl_coefficients": [-0.041065, 0.016292, 0.0002602],
            "cd_coefficients": [0.080505, -0.03026, 0.86495],
            "cd_argument": "cl",
        },
        "angle_of_attack": {"mode": "velocity_schedule"},
    },
    "planet": {
        "radius_m": 6378140,
        "g0_m_s2": 9.81,
        "rotation": False,
        "atmosphere": {
            "model": "exponential",
            "density_sea_level_kg_m3": 1.225,
            "scale_height_m": 8420,
        },
    },
    "initial_state": {
        "altitude_m": 105000,
        "longitude_deg": 0,
        "latitude_deg": 0,
        "velocity_m_s": 7449.81,
        "flight_path_angle_deg": -0.5,
        "heading_deg": 0,
    },
    "terminal": {
        "altitude_m": 30000,
        "longitude_deg": {"kind": "soft", "value": 15, "weight": 200},
        "latitude_deg": {"kind": "soft", "value": 70, "weight": 200},
        "flight_path_angle_deg": -10,
        "heading_deg": 15,
    },
    "energy": {"initial": 0.5403, "final": 0.9888},
    "path_constraints": {
        "heat_rate": {"max_W_m2": 1.0e6, "k_q": 9.4369e-5},
        "dynamic_pressure": {"max_Pa": 17000},
        "load_factor": {"max_g": 3.5},
    },
    "control_limits": {"bank_max_deg": 80},
    "objective": "min_heat_load",
    "method": {"name": "energy-scp", "nodes": 120},
}
"""Minimum heat load entry of an X-33-like reusable launch vehicle (Jung et al., simulation 1)."""
