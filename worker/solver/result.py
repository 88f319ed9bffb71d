"""Assemble the result document from an optimized trajectory, its verification and history."""

from __future__ import annotations

import math
import platform
import sys
from datetime import UTC, datetime
from importlib import metadata
from typing import Any

import numpy as np

from app.schemas.result import ResultDocument
from worker.solver.path_limits import path_values
from worker.solver.problem import EntryProblem
from worker.solver.verification import OptimizedTrajectory

UNITS = {
    "time_s": "s",
    "altitude_m": "m",
    "longitude_deg": "deg",
    "latitude_deg": "deg",
    "velocity_m_s": "m/s",
    "flight_path_angle_deg": "deg",
    "heading_deg": "deg",
    "bank_deg": "deg",
    "alpha_deg": "deg",
    "heat_rate_W_m2": "W/m^2",
    "dynamic_pressure_Pa": "Pa",
    "load_factor_g": "g0",
    "energy": "1 (e = R0/r - V^2/(2 g0 R0))",
}
PACKAGES = ("numpy", "scipy", "clarabel", "cvxpy", "pydantic", "entry-trajopt")


def trajectory_columns(problem: EntryProblem, traj: OptimizedTrajectory) -> dict[str, Any]:
    """The optimizer's nodes as named columns in SI units and degrees."""
    sc = problem.scales
    y = traj.y
    ft = problem.forces.terms(y[:, 0], y[:, 3], traj.alpha_deg)
    pv = path_values(problem.forces, problem.heat_model, y[:, 0], y[:, 3], ft)
    cols: dict[str, Any] = {
        "time_s": (traj.t * sc.time_s + problem.t0).tolist(),
        "altitude_m": ((y[:, 0] - 1.0) * sc.radius_m).tolist(),
        "longitude_deg": np.degrees(y[:, 1]).tolist(),
        "latitude_deg": np.degrees(y[:, 2]).tolist(),
        "velocity_m_s": (y[:, 3] * sc.speed_m_s).tolist(),
        "flight_path_angle_deg": np.degrees(y[:, 4]).tolist(),
        "heading_deg": np.degrees(y[:, 5]).tolist(),
        "bank_deg": np.degrees(traj.bank).tolist(),
        "alpha_deg": np.asarray(ft.alpha_deg, dtype=float).tolist(),
        "heat_rate_W_m2": pv.heat_rate.tolist() if problem.heat_model else None,
        "dynamic_pressure_Pa": pv.dynamic_pressure.tolist(),
        "load_factor_g": pv.load_factor.tolist(),
    }
    if traj.grid_kind == "energy":
        cols["energy"] = traj.grid.tolist()
    cols = {k: v for k, v in cols.items() if v is not None}
    cols["units"] = {k: UNITS[k] for k in cols}
    cols["nodes"] = int(y.shape[0])
    return cols


def _version(name: str) -> str | None:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def provenance(problem: EntryProblem) -> dict[str, Any]:
    """Package versions, options and platform: what is needed to reproduce the result."""
    return {
        "created_at": datetime.now(UTC).isoformat(),
        "packages": {name: _version(name) for name in PACKAGES},
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "method_options": problem.document.method.model_dump(mode="json"),
        "problem_name": problem.document.name,
    }


def finite_or_none(value: float | None) -> float | None:
    """JSON has no NaN or infinity: map them to null."""
    if value is None or not math.isfinite(value):
        return None
    return float(value)


def sanitize(obj: Any) -> Any:
    """Recursively replace non-finite floats by None and numpy scalars by Python ones."""
    if isinstance(obj, dict):
        return {k: sanitize(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [sanitize(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float):
        return finite_or_none(obj)
    return obj


def validated(document: dict[str, Any]) -> dict[str, Any]:
    """Check a result against the public ResultDocument contract and return it JSON-ready."""
    clean = sanitize(document)
    ResultDocument.model_validate(clean)
    return clean
