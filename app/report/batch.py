"""A batch's summary: one row per child (its parameters, status, objective, key terminal and path
figures, iterations, time) as JSON rows, CSV, and a plot (objective against the grid's
parameter, the dispersion's terminal points, or the methods side by side)."""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from app.report.plots import DPI, FIGURE_SIZE_IN, PLOT_FORMATS, ZONE_COLOR

FIGURES = (
    ("final_altitude_m", "final_state", "altitude_m"),
    ("final_velocity_m_s", "final_state", "velocity_m_s"),
    ("final_latitude_deg", "final_state", "latitude_deg"),
    ("final_longitude_deg", "final_state", "longitude_deg"),
    ("final_time_s", "final_state", "time_s"),
    ("heat_rate_ratio", "path_maxima", "heat_rate_W_m2"),
    ("dynamic_pressure_ratio", "path_maxima", "dynamic_pressure_Pa"),
    ("load_factor_ratio", "path_maxima", "load_factor_g"),
)
"""Summary column -> where the verification holds it (propagated final state; peak / limit)."""

ROW_COLUMNS = (
    "index",
    "job_id",
    "status",
    "failure_code",
    "objective",
    "objective_units",
    "feasible",
    *(name for name, _, _ in FIGURES),
    "min_zone_clearance_deg",
    "iterations",
    "optimization_s",
    "verification_s",
)
"""The columns of a summary row after the parameters."""


def _number(value: Any) -> float | None:
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) else None


def parameter_label(path: str, value: Any) -> Any:
    """How a parameter's value shows in a row: the value, or a method's name for ``/method``."""
    if path == "/method" and isinstance(value, Mapping):
        return value.get("name")
    return value


def summary_row(
    index: int,
    job_id: str,
    parameters: Mapping[str, Any],
    status: str,
    error_code: str | None,
    result: Mapping[str, Any] | None,
) -> dict[str, Any]:
    """One child's row: parameters by path, then :data:`ROW_COLUMNS` (null where unknown)."""
    result = result or {}
    verification = result.get("verification") or {}
    objective = result.get("objective") or {}
    timing = result.get("timing") or {}
    row: dict[str, Any] = {
        "index": index,
        "job_id": job_id,
        "parameters": {path: parameter_label(path, v) for path, v in parameters.items()},
        "status": status,
        "failure_code": error_code or (result.get("failure") or {}).get("code"),
        "objective": _number(objective.get("value")),
        "objective_units": objective.get("units"),
        "feasible": verification.get("feasible"),
    }
    for name, block, key in FIGURES:
        entry = (verification.get(block) or {}).get(key)
        if block == "path_maxima":
            row[name] = _number((entry or {}).get("ratio"))
        else:
            row[name] = _number(entry)
    clearances = [
        _number(z.get("min_clearance_deg")) for z in verification.get("no_fly_zones") or []
    ]
    known = [c for c in clearances if c is not None]
    row["min_zone_clearance_deg"] = min(known) if known else None
    row["iterations"] = timing.get("iterations")
    row["optimization_s"] = _number(timing.get("wall_s"))
    row["verification_s"] = _number(timing.get("verification_s"))
    return row


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, dict | list):
        return json.dumps(value, separators=(",", ":"))
    return str(value)


def summary_csv(rows: Iterable[Mapping[str, Any]], paths: Sequence[str]) -> str:
    """The rows as CSV: ``index, job_id``, one column per parameter path, then the rest."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    rest = ROW_COLUMNS[2:]
    writer.writerow(["index", "job_id", *paths, *rest])
    for row in rows:
        values = [row["parameters"].get(path) for path in paths]
        writer.writerow(
            [_cell(v) for v in (row["index"], row["job_id"], *values)]
            + [_cell(row[c]) for c in rest]
        )
    return out.getvalue()


def _objective(rows: Sequence[Mapping[str, Any]]) -> tuple[np.ndarray, np.ndarray]:
    """Objective per row (NaN where unknown) and whether the row succeeded."""
    values = np.array([np.nan if r["objective"] is None else r["objective"] for r in rows])
    ok = np.array([r["status"] == "succeeded" for r in rows], dtype=bool)
    return values, ok


def _objective_label(rows: Sequence[Mapping[str, Any]]) -> str:
    units = next((r["objective_units"] for r in rows if r.get("objective_units")), None)
    return f"objective ({units})" if units else "objective"


def _grid_plot(fig: Figure, rows: Sequence[Mapping[str, Any]], paths: Sequence[str]) -> None:
    ax = fig.add_subplot()
    values, ok = _objective(rows)
    firsts = [_number(r["parameters"].get(paths[0])) for r in rows]
    numeric = all(v is not None for v in firsts) and len(paths) <= 2
    if not numeric:
        x = np.array([r["index"] for r in rows], dtype=float)
        ax.plot(x[ok], values[ok], "o", label="succeeded")
        ax.plot(x[~ok], values[~ok], "x", color=ZONE_COLOR, label="did not succeed")
        ax.set_xlabel("child")
    else:
        x = np.array(firsts, dtype=float)
        groups: dict[Any, list[int]] = {}
        for i, row in enumerate(rows):
            key = row["parameters"].get(paths[1]) if len(paths) == 2 else None
            groups.setdefault(json.dumps(key), []).append(i)
        for key, members in groups.items():
            m = np.array(members)
            label = f"{paths[1]} = {json.loads(key)}" if len(paths) == 2 else "objective"
            ax.plot(x[m], np.where(ok[m], values[m], np.nan), "o-", label=label)
        failed = ~ok
        if failed.any():
            ax.plot(x[failed], values[failed], "x", color=ZONE_COLOR, label="did not succeed")
        ax.set_xlabel(paths[0])
    ax.set_ylabel(_objective_label(rows))
    ax.legend(loc="best", fontsize="small")
    ax.set_title("Objective across the grid")


def _monte_carlo_plot(fig: Figure, rows: Sequence[Mapping[str, Any]]) -> None:
    ax = fig.add_subplot()
    lon = np.array(
        [np.nan if r["final_longitude_deg"] is None else r["final_longitude_deg"] for r in rows]
    )
    lat = np.array(
        [np.nan if r["final_latitude_deg"] is None else r["final_latitude_deg"] for r in rows]
    )
    values, ok = _objective(rows)
    if ok.any():
        points = ax.scatter(lon[ok], lat[ok], c=values[ok], cmap="viridis", s=24)
        fig.colorbar(points, ax=ax, label=_objective_label(rows))
    if (~ok).any():
        ax.plot(lon[~ok], lat[~ok], "x", color=ZONE_COLOR, label="did not succeed")
        ax.legend(loc="best", fontsize="small")
    ax.set_xlabel("final longitude (deg)")
    ax.set_ylabel("final latitude (deg)")
    ax.set_title(f"Terminal points of {len(rows)} dispersed runs")


def _methods_plot(fig: Figure, rows: Sequence[Mapping[str, Any]]) -> None:
    ax = fig.add_subplot()
    values, ok = _objective(rows)
    names = [f"{r['index']}: {r['parameters'].get('/method')}" for r in rows]
    colors = ["#1f77b4" if good else ZONE_COLOR for good in ok]
    ax.bar(range(len(rows)), np.nan_to_num(values), color=colors)
    for i, row in enumerate(rows):
        seconds = row["optimization_s"]
        text = row["status"] if seconds is None else f"{row['status']}\n{seconds:.2f} s"
        ax.annotate(text, (i, 0), ha="center", va="bottom", fontsize="small", color="white")
    ax.set_xticks(range(len(rows)), names)
    ax.set_ylabel(_objective_label(rows))
    ax.set_title("One problem, several methods")


def _footprint_plot(
    fig: Figure,
    rows: Sequence[Mapping[str, Any]],
    tracks: Sequence[tuple[Sequence[float], Sequence[float]]],
) -> None:
    """The reachable set: each longitude's highest and lowest reached final latitude joined
    into an envelope, over the children's flown ground tracks."""
    ax = fig.add_subplot()
    for lon, lat in tracks:
        ax.plot(lon, lat, color="#9db4d0", linewidth=0.8)
    edges: dict[str, list[tuple[float, float]]] = {}
    for row in rows:
        lon, lat = row["final_longitude_deg"], row["final_latitude_deg"]
        if row["status"] == "succeeded" and lon is not None and lat is not None:
            edges.setdefault(str(row["parameters"].get("/objective")), []).append((lon, lat))
    upper = sorted(edges.get("max_final_latitude", []))
    lower = sorted(edges.get("min_final_latitude", []), reverse=True)
    ring = upper + lower
    if len(ring) >= 3:
        ax.fill(
            [p[0] for p in ring],
            [p[1] for p in ring],
            color="#1f77b4",
            alpha=0.2,
            label="reachable final points",
        )
    for points, style, label in (
        (upper, "o-", "highest final latitude"),
        (lower, "s-", "lowest final latitude"),
    ):
        if points:
            ax.plot([p[0] for p in points], [p[1] for p in points], style, label=label)
    failed = [r for r in rows if r["status"] != "succeeded"]
    if failed:
        ax.plot(
            [r["parameters"].get("/terminal/longitude_deg") for r in failed],
            [np.nan] * len(failed),
            "x",
            color=ZONE_COLOR,
            label=f"{len(failed)} not reached",
        )
    ax.set_xlabel("longitude (deg)")
    ax.set_ylabel("latitude (deg)")
    ax.set_title("Footprint: the reachable final points and the flown ground tracks")
    ax.legend(loc="best", fontsize="small")


def render_summary_plot(
    kind: str,
    rows: Sequence[Mapping[str, Any]],
    paths: Sequence[str],
    fmt: str,
    tracks: Sequence[tuple[Sequence[float], Sequence[float]]] = (),
) -> bytes:
    """The batch's plot as PNG or SVG bytes (``tracks``: the flown ground tracks of a
    footprint's children)."""
    if fmt not in PLOT_FORMATS:
        raise ValueError(f"format must be one of {sorted(PLOT_FORMATS)}, got {fmt!r}")
    fig = Figure(figsize=FIGURE_SIZE_IN, dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    if kind == "grid":
        _grid_plot(fig, rows, paths)
    elif kind == "monte_carlo":
        _monte_carlo_plot(fig, rows)
    elif kind == "footprint":
        _footprint_plot(fig, rows, tracks)
    else:
        _methods_plot(fig, rows)
    buffer = io.BytesIO()
    metadata = {"Date": None} if fmt == "svg" else {}
    fig.savefig(buffer, format=fmt, dpi=DPI, metadata=metadata)
    return buffer.getvalue()
