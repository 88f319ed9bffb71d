"""Assemble the result document from an optimized trajectory, its verification and history, and
say honestly what is wrong with it: non-finite values, constraints the nodes do not meet."""

from __future__ import annotations

import platform
import sys
from datetime import UTC, datetime
from typing import Any

import numpy as np

from app.schemas import ProblemDocument
from app.schemas.fingerprint import problem_sha256
from app.schemas.result import ResultDocument, json_ready
from worker.solver.constraints.no_fly import zone_distance
from worker.solver.models.bank_state_compiled import compiled_parameters
from worker.solver.path_limits import path_values
from worker.solver.phased_problem import PhasedProblem
from worker.solver.problem import EntryProblem
from worker.solver.scp.history import IterationRecord
from worker.solver.scp.loop import VIRTUAL_CONTROL_TOL
from worker.solver.software import library_versions, software
from worker.solver.trajectory import TIME_STATE_NAMES, OptimizedTrajectory, PhasedTrajectory
from worker.solver.units import COLUMN_UNITS
from worker.solver.verification import (
    VerificationTolerances,
    lift_control_column,
    terminal_error,
    to_si,
)
from worker.solver.verification_phased import (
    PATH_KEYS,
    path_columns,
    path_limit,
    phase_path_values,
    phased_columns,
)


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
        lift_control_column(problem): np.asarray(ft.alpha_deg, dtype=float).tolist(),
        "heat_rate_W_m2": pv.heat_rate.tolist() if problem.heat_model else None,
        "dynamic_pressure_Pa": pv.dynamic_pressure.tolist(),
        "load_factor_g": pv.load_factor.tolist(),
    }
    if traj.grid_kind == "energy":
        cols["energy"] = traj.grid.tolist()
    cols = {k: v for k, v in cols.items() if v is not None}
    cols["units"] = {k: COLUMN_UNITS[k] for k in cols}
    cols["nodes"] = int(y.shape[0])
    return cols


def dynamics_path(problem: EntryProblem) -> dict[str, str]:
    """Whether the problem's equations of motion have a compiled form; without one they run as
    numpy code, and the note says which models are the reason."""
    if compiled_parameters(problem.forces, problem.omega) is not None:
        return {"dynamics": "compiled"}
    forces = problem.forces
    models = (
        f"atmosphere {type(forces.atmosphere).__name__}, aerodynamics "
        f"{type(forces.aero).__name__}, angle of attack {type(forces.alpha_schedule).__name__}"
    )
    return {
        "dynamics": "numpy",
        "dynamics_note": f"no compiled form for these models ({models}); numpy code, slower",
    }


def input_provenance(document: ProblemDocument) -> dict[str, Any]:
    """What any result says of its input and its software, a solve or not: the problem's
    fingerprint and name, the method's options (defaults filled in), the job it started from,
    the library versions, this project's version and revision, Python and the platform."""
    guess = document.initial_guess
    source = guess.from_job if guess is not None else None
    return {
        "created_at": datetime.now(UTC).isoformat(),
        "problem_name": document.name,
        "problem_sha256": problem_sha256(document),
        "method_options": document.method.model_dump(mode="json"),
        **({"source_job": source} if source is not None else {}),
        "packages": library_versions(),
        "software": software(),
        "python": sys.version.split()[0],
        "platform": platform.platform(),
    }


def provenance(problem: EntryProblem, about_input: dict[str, Any]) -> dict[str, Any]:
    """``about_input`` (:func:`input_provenance`) and how the solve ran: the dynamics path and
    the start; what is needed to reproduce the result and to explain its time."""
    return {
        **about_input,
        "created_at": datetime.now(UTC).isoformat(),
        **dynamics_path(problem),
        **_guess_note(problem),
    }


def _guess_note(problem: EntryProblem) -> dict[str, str]:
    """Where the method started when it was given an initial guess (nothing otherwise)."""
    if problem.guess is None:
        return {}
    return {"initial_guess": f"the given trajectory ({problem.guess.t.size} points)"}


def validated(document: dict[str, Any]) -> dict[str, Any]:
    """Check a result against the public ResultDocument contract (every nested record typed)
    and return it JSON-ready; the document itself is returned, not the model's dump, so no
    default is added to it."""
    clean: dict[str, Any] = json_ready(document)
    ResultDocument.model_validate(clean)
    return clean


def node_violations(
    problem: EntryProblem,
    traj: OptimizedTrajectory,
    record: IterationRecord | None,
    tolerances: VerificationTolerances | None = None,
) -> list[str]:
    """What the reported nodes do not meet, with where and by how much: virtual control that
    did not vanish (the last iteration's norm over ``VIRTUAL_CONTROL_TOL``), a no-fly zone
    entered or a path limit exceeded at a node by more than the verification accepts (the same
    margins, so a result is not called infeasible for what verification tolerates)."""
    tol = tolerances or VerificationTolerances()
    sc = problem.scales
    out: list[str] = []
    if record is not None and record.virtual_control_norm > VIRTUAL_CONTROL_TOL:
        out.append(
            f"virtual control did not vanish (norm {record.virtual_control_norm:.3g} at "
            f"iteration {record.iteration}, tolerance {VIRTUAL_CONTROL_TOL:g})"
        )
    y = traj.y
    t_s = traj.t * sc.time_s + problem.t0
    for k, zone in enumerate(problem.no_fly_zones):
        clearance = np.degrees(zone_distance(y[:, 2], y[:, 1], zone).c - zone.radius)
        node = int(np.argmin(clearance))
        if clearance[node] < -tol.no_fly_zone_deg:
            name = f" ({zone.name})" if zone.name else ""
            out.append(
                f"no-fly zone {k}{name} penetrated by {-clearance[node]:.3g} deg at "
                f"t = {t_s[node]:.1f} s (node {node})"
            )
    ft = problem.forces.terms(y[:, 0], y[:, 3], traj.alpha_deg)
    pv = path_values(problem.forces, problem.heat_model, y[:, 0], y[:, 3], ft)
    lim = problem.limits
    for label, values, limit in (
        ("heat rate", pv.heat_rate if problem.heat_model else None, lim.heat_max_W_m2),
        ("dynamic pressure", pv.dynamic_pressure, lim.dynamic_pressure_max_Pa),
        ("load factor", pv.load_factor, lim.load_factor_max_g),
    ):
        if values is None or limit is None:
            continue
        node = int(np.argmax(values))
        ratio = float(values[node]) / limit
        if ratio > 1.0 + tol.path_limit_relative:
            out.append(f"{label} {ratio:.4f} of its limit at t = {t_s[node]:.1f} s (node {node})")
    return out


def _phase_node_path(problem: PhasedProblem, traj: PhasedTrajectory) -> dict[str, np.ndarray]:
    """The path quantities at every node, each under its own phase's heat model."""
    out = {key: np.zeros(traj.t.size) for key in PATH_KEYS}
    for p, phase in enumerate(problem.phases):
        mask = traj.phase == p
        if np.any(mask):
            values = path_columns(phase_path_values(problem, phase, traj.x[mask], traj.u[mask]))
            for key in PATH_KEYS:
                out[key][mask] = values[key]
    return out


def phased_trajectory_columns(problem: PhasedProblem, traj: PhasedTrajectory) -> dict[str, Any]:
    """The nodes of a flight in phases as named columns in SI units and degrees: those of
    ``trajectory_columns``, then mass, thrust acting and commanded (with propulsion) and each
    node's phase index."""
    path = _phase_node_path(problem, traj)
    columns = phased_columns(problem, traj.t, traj.x, traj.u, path, traj.phase)
    cols: dict[str, Any] = {k: v.tolist() for k, v in columns.items()}
    cols["units"] = {k: COLUMN_UNITS[k] for k in columns}
    cols["nodes"] = int(traj.t.size)
    return cols


_PATH_LABELS = {
    "heat_rate_W_m2": "heat rate",
    "dynamic_pressure_Pa": "dynamic pressure",
    "load_factor_g": "load factor",
}


def phased_node_violations(
    problem: PhasedProblem,
    traj: PhasedTrajectory,
    tolerances: VerificationTolerances | None = None,
) -> list[str]:
    """What the reported nodes of a flight in phases do not meet, with the phase, where and by
    how much: a no-fly zone entered, a path limit of the node's phase exceeded, or a fixed or
    range end condition of a phase missed at its last node, by more than the verification
    accepts (its margins)."""
    tol = tolerances or VerificationTolerances()
    sc = problem.base.scales
    t_s = traj.t * sc.time_s + problem.base.t0
    out: list[str] = []
    x = traj.x
    for k, zone in enumerate(problem.base.no_fly_zones):
        clearance = np.degrees(zone_distance(x[:, 2], x[:, 1], zone).c - zone.radius)
        node = int(np.argmin(clearance))
        if clearance[node] < -tol.no_fly_zone_deg:
            name = f" ({zone.name})" if zone.name else ""
            out.append(
                f"no-fly zone {k}{name} penetrated by {-clearance[node]:.3g} deg at "
                f"t = {t_s[node]:.1f} s (node {node}, phase {int(traj.phase[node])})"
            )
    path = _phase_node_path(problem, traj)
    for p, phase in enumerate(problem.phases):
        nodes = np.flatnonzero(traj.phase == p)
        if nodes.size == 0:
            continue
        where = f"phase {p} ({phase.name})"
        for key, label in _PATH_LABELS.items():
            limit = path_limit(phase, key)
            if limit is None:
                continue
            node = int(nodes[np.argmax(path[key][nodes])])
            ratio = float(path[key][node]) / limit
            if ratio > 1.0 + tol.path_limit_relative:
                out.append(
                    f"{where}: {label} {ratio:.4f} of its limit at t = {t_s[node]:.1f} s "
                    f"(node {node})"
                )
        end = int(nodes[-1])
        final = to_si(problem.base, x[end, :6])
        for name in TIME_STATE_NAMES:
            spec = phase.end_si[name]
            if spec.kind not in ("fixed", "range"):
                continue
            err = terminal_error(spec, final[name])
            tolerance = getattr(tol, name)
            if abs(err) > tolerance:
                out.append(
                    f"{where}: end {name} off by {err:.4g} (tolerance {tolerance:g}) at "
                    f"t = {t_s[end]:.1f} s (node {end})"
                )
    return out
