"""The optimized trajectory of a result document as CSV: one row per node, units in the header."""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping
from typing import Any

NOT_COLUMNS = frozenset({"units", "nodes"})
"""Keys of the trajectory object that are not per-node columns."""


class NoTrajectoryError(ValueError):
    """The result document holds no trajectory (the solve produced none)."""


def trajectory_columns(result: Mapping[str, Any]) -> dict[str, list[Any]]:
    """The per-node columns of ``result``'s trajectory, in the document's order."""
    trajectory = result.get("trajectory")
    if not isinstance(trajectory, Mapping):
        raise NoTrajectoryError("the result has no trajectory")
    return {
        name: list(values)
        for name, values in trajectory.items()
        if name not in NOT_COLUMNS and isinstance(values, list)
    }


def header_label(name: str, units: Mapping[str, str]) -> str:
    """A column's CSV header: its name and, when known, its unit in brackets."""
    unit = units.get(name)
    return f"{name} [{unit}]" if unit else name


def trajectory_csv(result: Mapping[str, Any]) -> str:
    """``result``'s trajectory as CSV text (comma-separated, a header row, ``\\n`` line ends).

    Values are written with Python's shortest round-trip repr, so parsing the CSV gives back
    the document's numbers exactly; a null (a non-finite value) is an empty cell.
    """
    columns = trajectory_columns(result)
    units = result["trajectory"].get("units") or {}
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow([header_label(name, units) for name in columns])
    for row in zip(*columns.values(), strict=True):
        writer.writerow(["" if value is None else repr(value) for value in row])
    return out.getvalue()
