"""The capability matrix: which method takes which feature, read from the methods' own checks.

Each feature is switched on, alone, in a small document (paper 000's vehicle and entry, free
final time, a velocity schedule of the angle of attack); a method takes the feature when its
support check names no issue at the feature's field. Phases, propulsion and the objectives are
the methods' declared flags and objective lists (which their checks read). ``GET /v1/methods``
serves the matrix; auto's rule reads the same checks, on the document itself.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from functools import cache
from typing import Any, NamedTuple, get_args

from app.schemas import ProblemDocument
from app.schemas.objective import ObjectiveName
from worker.solver.methods import registry
from worker.solver.scenarios import get_scenario

Patch = Callable[[dict[str, Any]], None]


class Probe(NamedTuple):
    """One feature: its group and key in the matrix, the field its refusal names, its patch."""

    group: str
    key: str
    field: str
    patch: Patch


def _set(path: str, value: Any) -> Patch:
    """A patch setting the dotted ``path`` to ``value``."""

    def apply(doc: dict[str, Any]) -> None:
        *parents, last = path.split(".")
        node = doc
        for part in parents:
            node = node.setdefault(part, {})
        node[last] = copy.deepcopy(value)

    return apply


def _no_change(doc: dict[str, Any]) -> None:
    """The base document as it is."""


def _fixed_final_time(doc: dict[str, Any]) -> None:
    doc["final_time"] = {"kind": "fixed", "value_s": 1600.0}
    doc["energy"] = None


def _optimized_alpha(doc: dict[str, Any]) -> None:
    doc["vehicle"]["angle_of_attack"] = {"mode": "optimized", "min_deg": 5.0, "max_deg": 30.0}


def _alpha_rate(doc: dict[str, Any]) -> None:
    _optimized_alpha(doc)
    doc["control_limits"]["alpha_rate_max_deg_s"] = 5.0


def _table_aero(doc: dict[str, Any]) -> None:
    doc["vehicle"]["aerodynamics"] = {
        "model": "table",
        "alpha_deg": [0.0, 45.0],
        "mach": [0.0, 30.0],
        "cl": [[0.0, 0.0], [0.9, 0.9]],
        "cd": [[0.08, 0.08], [0.9, 0.9]],
    }


def _polar_aero(doc: dict[str, Any]) -> None:
    doc["vehicle"]["aerodynamics"] = {
        "model": "parabolic_polar",
        "cl_star": 0.4,
        "cd0": 0.05,
        "k_induced": 0.5,
    }
    doc["vehicle"]["angle_of_attack"] = None


PROBES: tuple[Probe, ...] = (
    Probe("final_time", "free", "final_time", _no_change),
    Probe("final_time", "fixed", "final_time", _fixed_final_time),
    Probe("angle_of_attack", "scheduled", "vehicle.angle_of_attack", _no_change),
    Probe("angle_of_attack", "optimized", "vehicle.angle_of_attack", _optimized_alpha),
    Probe(
        "limits",
        "no_fly_zones",
        "no_fly_zones",
        _set(
            "no_fly_zones",
            [{"center_latitude_deg": 30.0, "center_longitude_deg": 40.0, "radius_deg": 1.0}],
        ),
    ),
    Probe(
        "limits",
        "waypoints",
        "waypoints",
        _set(
            "waypoints",
            [{"latitude_deg": 30.0, "longitude_deg": 5.0, "radius_deg": 1.0, "order": 0}],
        ),
    ),
    Probe(
        "limits",
        "bank_rate_limit",
        "control_limits.bank_rate_max_deg_s",
        _set("control_limits.bank_rate_max_deg_s", 10.0),
    ),
    Probe(
        "limits",
        "asymmetric_bank_range",
        "control_limits.bank_min_deg",
        _set("control_limits.bank_min_deg", -60.0),
    ),
    Probe("limits", "alpha_rate_limit", "control_limits.alpha_rate_max_deg_s", _alpha_rate),
    Probe("limits", "soft_terminal_conditions", "terminal.", _no_change),
    Probe("atmosphere", "exponential", "planet.atmosphere", _no_change),
    Probe("atmosphere", "us76", "planet.atmosphere", _set("planet.atmosphere", {"model": "us76"})),
    Probe("aerodynamics", "polynomial", "vehicle.aerodynamics", _no_change),
    Probe("aerodynamics", "table", "vehicle.aerodynamics", _table_aero),
    Probe("aerodynamics", "parabolic_polar", "vehicle.aerodynamics", _polar_aero),
    Probe("planet", "spherical", "planet.model", _no_change),
    Probe("planet", "flat", "planet.model", _set("planet.model", "flat")),
)
"""Each probed feature; the base (paper 000's problem, which has soft terminal targets) is
changed by the patch alone."""

GROUPS: dict[str, str] = {
    "final_time": "final time",
    "angle_of_attack": "angle of attack",
    "limits": "constraints and targets",
    "atmosphere": "atmosphere",
    "aerodynamics": "aerodynamics",
    "planet": "planet model",
    "flight": "flight",
    "objectives": "objective terms",
}
"""Each group of the matrix and how the docs name it."""


def _base() -> dict[str, Any]:
    """The probes' base document: paper 000's problem without its method."""
    doc = copy.deepcopy(get_scenario("rlv-min-heat-load").problem)
    doc.pop("method", None)
    return doc


def _takes(name: str, probe: Probe) -> bool:
    """Whether method ``name``'s support check lets ``probe``'s feature pass."""
    doc = _base()
    probe.patch(doc)
    doc["method"] = {"name": name}
    issues = registry.check_support(ProblemDocument.model_validate(doc))
    return not any(i.field.startswith(probe.field) for i in issues)


@cache
def capability_matrix() -> dict[str, dict[str, dict[str, bool]]]:
    """Method -> group -> feature -> whether the method takes it (probed once per process)."""
    objectives = get_args(ObjectiveName)
    matrix: dict[str, dict[str, dict[str, bool]]] = {}
    for name, info in registry.METHODS.items():
        row: dict[str, dict[str, bool]] = {group: {} for group in GROUPS}
        for probe in PROBES:
            row[probe.group][probe.key] = _takes(name, probe)
        row["flight"] = {"phases": info.phases, "propulsion": info.propulsion}
        row["objectives"] = {term: term in info.objectives for term in objectives}
        matrix[name] = row
    return matrix


def matrix_table() -> str:
    """The matrix as a Markdown table (features as rows, methods as columns), as the docs show
    it."""
    matrix = capability_matrix()
    names = list(matrix)
    lines = [
        "| feature | " + " | ".join(f"`{n}`" for n in names) + " |",
        "| --- |" + " --- |" * len(names),
    ]
    first = matrix[names[0]]
    for group, features in first.items():
        for key in features:
            marks = ["yes" if matrix[n][group][key] else "–" for n in names]
            lines.append(f"| {GROUPS[group]}: `{key}` | " + " | ".join(marks) + " |")
    return "\n".join(lines)
