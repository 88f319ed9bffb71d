"""``GET /v1/methods``: every method with its features, default options, place in auto's order
and row of the capability matrix, and ``auto`` itself (its rule, and what any method takes)."""

from __future__ import annotations

from typing import Any, get_args

from app.schemas.methods import AUTO, AutoOptions
from app.schemas.objective import ObjectiveName
from worker.solver.methods.capabilities import capability_matrix
from worker.solver.methods.registry import METHODS
from worker.solver.methods.selection import PREFERENCE


def _auto_entry(matrix: dict[str, dict[str, dict[str, bool]]]) -> dict[str, Any]:
    """``auto`` as a method: its rule as features, and a feature as taken when any method
    takes it."""
    rows = list(matrix.values())
    reach = {
        group: {key: any(row[group][key] for row in rows) for key in features}
        for group, features in rows[0].items()
    }
    return {
        "name": AUTO,
        "title": "Automatic choice: the methods that accept the problem, tried in a documented "
        "order within one time budget (the default when a document names no method)",
        "paper": "",
        "features": [
            f"{rank}. {entry.name}: {entry.reason}" for rank, entry in enumerate(PREFERENCE, 1)
        ],
        "objectives": [t for t in get_args(ObjectiveName) if reach["objectives"][t]],
        "phases": reach["flight"]["phases"],
        "propulsion": reach["flight"]["propulsion"],
        "default_options": AutoOptions().model_dump(mode="json"),
        "preference": None,
        "capabilities": reach,
    }


def list_methods() -> list[dict[str, Any]]:
    """``auto``, then every method, JSON-ready."""
    matrix = capability_matrix()
    rank = {entry.name: i for i, entry in enumerate(PREFERENCE, 1)}
    methods = [
        {**info.describe(), "preference": rank[name], "capabilities": matrix[name]}
        for name, info in METHODS.items()
    ]
    return [_auto_entry(matrix), *methods]
