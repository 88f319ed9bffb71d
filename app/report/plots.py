"""Plots of a result document, rendered with matplotlib's object API (no pyplot, no display, so
concurrent requests of the service never share a figure).

Each plot overlays the optimized nodes (markers) on the propagated flight of the verification
(a line through about 20 samples between nodes): what the method promised and what the
controls actually fly. Limits are dashed lines; no-fly zones are drawn to scale on the ground
track (great-circle circles on an equirectangular map with the aspect of the mid latitude).
"""

from __future__ import annotations

import io
import json
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import matplotlib
import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

if matplotlib.rcParams["svg.hashsalt"] is None:
    # fixed SVG element ids (set once: rcParams are the process's, shared by every thread), so
    # the same result renders to the same bytes
    matplotlib.rcParams["svg.hashsalt"] = "trajopt"

PLOT_FORMATS = {"png": "image/png", "svg": "image/svg+xml"}
"""File formats a plot renders to, with their media types."""

FIGURE_SIZE_IN = (8.0, 5.0)
DPI = 100
"""A plot is 800 x 500 pixels as PNG."""

ZONE_COLOR = "#d62728"
WAYPOINT_COLOR = "#2ca02c"
NODE_STYLE: dict[str, Any] = {"marker": "o", "markersize": 3.5, "linestyle": "none"}
FLOWN_STYLE: dict[str, Any] = {"linewidth": 1.3, "color": "#1f77b4"}
LIMIT_STYLE: dict[str, Any] = {"linestyle": "--", "color": ZONE_COLOR, "linewidth": 1.0}

PATH_PLOTS = {
    "heat-rate": ("heat_rate_W_m2", "heat rate", 1e-3, "kW/m²"),
    "dynamic-pressure": ("dynamic_pressure_Pa", "dynamic pressure", 1e-3, "kPa"),
    "load-factor": ("load_factor_g", "load factor", 1.0, "g0"),
}
"""Plot name -> (column, label, factor to the plotted unit, plotted unit)."""

Result = Mapping[str, Any]


class UnknownPlotError(KeyError):
    """No plot ``name`` for this result; ``available`` lists the plots it has."""

    def __init__(self, name: str, available: Sequence[str] = ()) -> None:
        super().__init__(name, list(available))
        self.name = name
        self.available = list(available)


def _columns(result: Result, key: str) -> dict[str, np.ndarray]:
    """The numeric columns of the trajectory (``key`` "trajectory") or the propagated flight
    (``key`` "propagated", inside the verification); empty when absent. Nulls become NaN."""
    owner = result if key == "trajectory" else result.get("verification")
    block = owner.get(key) if isinstance(owner, Mapping) else None
    if not isinstance(block, Mapping):
        return {}
    return {
        name: np.array([np.nan if v is None else v for v in values], dtype=float)
        for name, values in block.items()
        if isinstance(values, list)
    }


def _overlay(
    ax: Axes,
    result: Result,
    x: str,
    y: str,
    *,
    x_factor: float = 1.0,
    y_factor: float = 1.0,
) -> None:
    """The propagated flight (line) and the optimized nodes (markers) of column ``y`` against
    column ``x``."""
    flown, nodes = _columns(result, "propagated"), _columns(result, "trajectory")
    if x in flown and y in flown:
        ax.plot(flown[x] * x_factor, flown[y] * y_factor, label="propagated", **FLOWN_STYLE)
    if x in nodes and y in nodes:
        ax.plot(
            nodes[x] * x_factor,
            nodes[y] * y_factor,
            label="optimized (nodes)",
            color="#ff7f0e",
            **NODE_STYLE,
        )


def _slope(values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """d values / dt between samples, each run of increasing times on its own: a flight in
    phases repeats the time where one phase hands over to the next (its control may jump)."""
    out = np.full(values.shape, np.nan)
    cuts = np.flatnonzero(np.diff(t) <= 0.0) + 1
    for run in np.split(np.arange(t.size), cuts):
        if run.size > 1:
            out[run] = np.gradient(values[run], t[run])
    return out


def _phase_changes(ax: Axes, result: Result) -> None:
    """A dotted vertical line where one phase of a flight in phases hands over to the next."""
    nodes = _columns(result, "trajectory")
    if "phase" in nodes and "time_s" in nodes:
        changes = np.flatnonzero(np.diff(nodes["phase"]) != 0) + 1
        for k, at in enumerate(nodes["time_s"][changes]):
            label = None if k else "phase change"
            ax.axvline(at, color="grey", linewidth=0.8, linestyle=":", label=label)


def _limit(ax: Axes, value: float | None, label: str) -> None:
    """A dashed horizontal line at a limit, if there is one."""
    if value is not None and math.isfinite(value):
        ax.axhline(value, label=label, **LIMIT_STYLE)


def _altitude_velocity(fig: Figure, result: Result) -> None:
    ax = fig.add_subplot()
    _overlay(ax, result, "velocity_m_s", "altitude_m", x_factor=1e-3, y_factor=1e-3)
    ax.set_xlabel("velocity (km/s)")
    ax.set_ylabel("altitude (km)")
    ax.set_title("Altitude against velocity")
    ax.legend(loc="best")


def zone_outline(zone: Mapping[str, Any], points: int = 181) -> tuple[np.ndarray, np.ndarray]:
    """Longitudes and latitudes (deg) of a no-fly zone's boundary: the points at the zone's
    radius from its centre, along the sphere (great_circle: the destination-point formula) or
    in the latitude-longitude plane (lat_lon)."""
    lat0, lon0 = math.radians(zone["latitude_deg"]), math.radians(zone["longitude_deg"])
    radius = math.radians(zone["radius_deg"])
    bearing = np.linspace(0.0, 2.0 * math.pi, points)
    if zone.get("metric") == "lat_lon":
        return np.degrees(lon0 + radius * np.cos(bearing)), np.degrees(
            lat0 + radius * np.sin(bearing)
        )
    lat = np.arcsin(
        math.sin(lat0) * math.cos(radius) + math.cos(lat0) * math.sin(radius) * np.cos(bearing)
    )
    lon = lon0 + np.arctan2(
        np.sin(bearing) * math.sin(radius) * math.cos(lat0),
        math.cos(radius) - math.sin(lat0) * np.sin(lat),
    )
    return np.degrees(lon), np.degrees(lat)


def _ground_track(fig: Figure, result: Result) -> None:
    ax = fig.add_subplot()
    zones = (result.get("verification") or {}).get("no_fly_zones") or []
    drawn = False
    for zone in zones:
        if zone.get("radius_deg") is None:
            continue  # a result stored before zones carried their geometry
        lon, lat = zone_outline(zone)
        ax.fill(lon, lat, color=ZONE_COLOR, alpha=0.35, label=None if drawn else "no-fly zone")
        ax.plot(lon, lat, color=ZONE_COLOR, linewidth=1.0)
        if zone.get("name"):
            top = (zone["longitude_deg"], zone["latitude_deg"] + zone["radius_deg"])
            ax.annotate(zone["name"], top, ha="center", va="bottom", fontsize="small")
        drawn = True
    for number, point in enumerate((result.get("verification") or {}).get("waypoints") or []):
        lon, lat = zone_outline(point)
        label = None if number else "waypoint"
        ax.plot(lon, lat, color=WAYPOINT_COLOR, linewidth=1.4, linestyle="--", label=label)
        top = (point["longitude_deg"], point["latitude_deg"] + point["radius_deg"])
        ax.annotate(f"{point['order']}", top, ha="center", va="bottom", color=WAYPOINT_COLOR)
    _overlay(ax, result, "longitude_deg", "latitude_deg")
    nodes = _columns(result, "trajectory")
    if "latitude_deg" in nodes and nodes["latitude_deg"].size:
        middle = math.radians(float(np.nanmean(nodes["latitude_deg"])))
        # equal distances at the mid latitude; the data limits widen to fill the figure
        ax.set_aspect(1.0 / max(math.cos(middle), 0.05), adjustable="datalim")
    ax.set_xlabel("longitude (deg)")
    ax.set_ylabel("latitude (deg)")
    ax.set_title("Ground track")
    ax.legend(loc="best")


def _states(fig: Figure, result: Result) -> None:
    panels = (
        ("altitude_m", "altitude (km)", 1e-3),
        ("velocity_m_s", "velocity (km/s)", 1e-3),
        ("flight_path_angle_deg", "flight-path angle (deg)", 1.0),
        ("heading_deg", "heading (deg)", 1.0),
    )
    axes = fig.subplots(2, 2, sharex=True)
    for ax, (column, label, factor) in zip(axes.flat, panels, strict=True):
        _overlay(ax, result, "time_s", column, y_factor=factor)
        ax.set_ylabel(label)
    for ax in axes[1]:
        ax.set_xlabel("time (s)")
    axes[0][0].legend(loc="best", fontsize="small")
    fig.suptitle("States against time")


def _controls(fig: Figure, result: Result) -> None:
    limits = (result.get("verification") or {}).get("control_limits") or {}
    nodes, flown = _columns(result, "trajectory"), _columns(result, "propagated")
    lift = "normalized_lift" if "normalized_lift" in nodes else "alpha_deg"
    show_alpha = lift in nodes and np.ptp(np.nan_to_num(nodes[lift])) > 0.0
    show_rate = "bank_deg" in flown and flown["bank_deg"].size > 2
    alpha_rate = (limits.get("alpha_rate_deg_s") or {}).get("limit")
    show_alpha_rate = show_alpha and alpha_rate is not None and "alpha_deg" in flown
    panels = 1 + int(show_rate) + int(show_alpha) + int(show_alpha_rate)
    axes = list(fig.subplots(panels, 1, sharex=True, squeeze=False)[:, 0])
    bank = axes.pop(0)
    _overlay(bank, result, "time_s", "bank_deg")
    high = (limits.get("bank_deg") or {}).get("limit")
    low = (limits.get("bank_min_deg") or {}).get("limit")
    _limit(bank, high, "limits")
    _limit(bank, low if low is not None else (-high if high is not None else None), "_")
    bank.set_ylabel("bank\n(deg)")
    bank.legend(loc="best", fontsize="small")
    if show_rate:  # the flown bank's slope between the propagation's samples
        rate_ax = axes.pop(0)
        rate = _slope(flown["bank_deg"], flown["time_s"])
        rate_ax.plot(flown["time_s"], rate, label="propagated", **FLOWN_STYLE)
        limit = (limits.get("bank_rate_deg_s") or {}).get("limit")
        _limit(rate_ax, limit, "limits")
        _limit(rate_ax, -limit if limit is not None else None, "_")
        rate_ax.set_ylabel("bank rate\n(deg/s)")
    if show_alpha:
        alpha = axes.pop(0)
        _overlay(alpha, result, "time_s", lift)
        for key in ("alpha_max_deg", "alpha_min_deg"):
            _limit(alpha, (limits.get(key) or {}).get("limit"), "_")
        label = "normalized\nlift (1)" if lift == "normalized_lift" else "angle of\nattack (deg)"
        alpha.set_ylabel(label)
    if show_alpha_rate:
        rate_ax = axes.pop(0)
        rate = _slope(flown["alpha_deg"], flown["time_s"])
        rate_ax.plot(flown["time_s"], rate, **FLOWN_STYLE)
        _limit(rate_ax, alpha_rate, "_")
        _limit(rate_ax, -alpha_rate if alpha_rate is not None else None, "_")
        rate_ax.set_ylabel("alpha rate\n(deg/s)")
    fig.axes[-1].set_xlabel("time (s)")
    fig.suptitle("Controls against time")


def _path_plot(name: str) -> Callable[[Figure, Result], None]:
    column, label, factor, unit = PATH_PLOTS[name]

    def draw(fig: Figure, result: Result) -> None:
        ax = fig.add_subplot()
        _overlay(ax, result, "time_s", column, y_factor=factor)
        peak = ((result.get("verification") or {}).get("path_maxima") or {}).get(column) or {}
        limit = peak.get("limit")
        phase = f" (phase {peak['phase']})" if peak.get("phase") else ""
        _limit(ax, None if limit is None else limit * factor, f"limit{phase}")
        _phase_changes(ax, result)
        ax.set_xlabel("time (s)")
        ax.set_ylabel(f"{label} ({unit})")
        ratio = peak.get("ratio")
        suffix = f": propagated peak {ratio:.4f} of the limit" if ratio is not None else ""
        ax.set_title(f"{label[0].upper()}{label[1:]}{suffix}")
        ax.legend(loc="best")

    return draw


def _mass_thrust(fig: Figure, result: Result) -> None:
    mass, thrust = fig.subplots(2, 1, sharex=True)
    _overlay(mass, result, "time_s", "mass_kg", y_factor=1e-3)
    mass.set_ylabel("mass (t)")
    _overlay(thrust, result, "time_s", "thrust_n", y_factor=1e-3)
    flown = _columns(result, "propagated")
    if "thrust_command_n" in flown and "time_s" in flown:
        thrust.plot(
            flown["time_s"],
            flown["thrust_command_n"] * 1e-3,
            label="commanded",
            color="grey",
            linestyle="--",
            linewidth=1.0,
        )
    thrust.set_ylabel("thrust (kN)")
    thrust.set_xlabel("time (s)")
    for ax in (mass, thrust):
        _phase_changes(ax, result)
    mass.legend(loc="best", fontsize="small")
    thrust.legend(loc="best", fontsize="small")
    fig.suptitle("Mass and thrust against time")


def run_boundaries(history: Sequence[Mapping[str, Any]]) -> list[int]:
    """The iterations (1-based) that begin another start of a multi-start run or another
    attempt of auto: where the record's (attempt, start) tag changes."""
    tags = [
        ((r.get("extra") or {}).get("auto_attempt"), (r.get("extra") or {}).get("start"))
        for r in history
    ]
    return [i + 1 for i in range(1, len(tags)) if tags[i] != tags[i - 1]]


def _convergence(fig: Figure, result: Result) -> None:
    history = result.get("history") or []
    index = np.arange(1, len(history) + 1)

    def series(read: Callable[[Mapping[str, Any]], Any]) -> np.ndarray:
        values = []
        for record in history:
            value = read(record)
            values.append(np.nan if value is None else float(value))
        return np.array(values, dtype=float)

    axes = fig.subplots(2, 2, sharex=True)
    cost = series(lambda r: r.get("objective_value", r.get("cost")))
    if np.all(np.isnan(cost)):
        cost = series(lambda r: r.get("cost"))
    axes[0][0].plot(index, cost, marker=".")
    axes[0][0].set_ylabel("objective")
    changes: dict[str, list[float]] = {}
    for record in history:
        for state, value in (record.get("max_state_change") or {}).items():
            changes.setdefault(state, []).append(np.nan if value is None else abs(float(value)))
    for state, values in changes.items():
        if len(values) == len(history):
            axes[0][1].semilogy(index, np.maximum(values, 1e-16), label=state)
    axes[0][1].set_ylabel("max state change (SI, deg)")
    if axes[0][1].get_legend_handles_labels()[0]:  # a state changed at every iteration
        axes[0][1].legend(fontsize="x-small", loc="best")
    virtual = series(lambda r: r.get("virtual_control_norm"))
    axes[1][0].semilogy(index, np.maximum(virtual, 1e-16), marker=".")
    axes[1][0].set_ylabel("virtual control (scaled)")
    weight = series(lambda r: (r.get("extra") or {}).get("weight_trust_region"))
    if not np.all(np.isnan(weight)):
        axes[1][1].semilogy(index, weight, marker=".")
    axes[1][1].set_ylabel("trust-region weight")
    for ax in axes.flat:
        for boundary in run_boundaries(history):
            ax.axvline(boundary - 0.5, color="grey", linewidth=0.8, linestyle=":")
    for ax in axes[1]:
        ax.set_xlabel("iteration (all starts and attempts in order)")
    fig.suptitle("Convergence")


PLOTS: dict[str, Callable[[Figure, Result], None]] = {
    "altitude-velocity": _altitude_velocity,
    "ground-track": _ground_track,
    "states": _states,
    "controls": _controls,
    **{name: _path_plot(name) for name in PATH_PLOTS},
    "mass-thrust": _mass_thrust,
    "convergence": _convergence,
}
"""Every plot a result can have, by name, in the order they are listed."""


def available_plots(result: Result) -> list[str]:
    """The names of the plots ``result`` has data for: the trajectory's (when there is one),
    each path quantity the problem defines, mass and thrust (with propulsion), and the
    convergence (when there is a history)."""
    nodes = _columns(result, "trajectory")
    names: list[str] = []
    if nodes:
        names += ["altitude-velocity", "ground-track", "states", "controls"]
        names += [name for name, spec in PATH_PLOTS.items() if spec[0] in nodes]
        if "mass_kg" in nodes and "thrust_n" in nodes:
            names.append("mass-thrust")
    if result.get("history"):
        names.append("convergence")
    return names


def figure(result: Result, name: str) -> Figure:
    """The figure of plot ``name`` for ``result``; UnknownPlotError when it has none."""
    names = available_plots(result)
    if name not in names:
        raise UnknownPlotError(name, names)
    fig = Figure(figsize=FIGURE_SIZE_IN, dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)  # its own raster canvas: no pyplot, no global backend
    PLOTS[name](fig, result)
    return fig


def render_plot(result: Result, name: str, fmt: str) -> bytes:
    """Plot ``name`` of ``result`` as ``fmt`` (a key of :data:`PLOT_FORMATS`) bytes."""
    if fmt not in PLOT_FORMATS:
        raise ValueError(f"format must be one of {sorted(PLOT_FORMATS)}, got {fmt!r}")
    buffer = io.BytesIO()
    metadata = {"Date": None} if fmt == "svg" else {}  # no creation date in the file
    figure(result, name).savefig(buffer, format=fmt, dpi=DPI, metadata=metadata)
    return buffer.getvalue()


def render_stored_plot(result_json: str, name: str, fmt: str) -> bytes:
    """Plot ``name`` of a result document given as its JSON text (as the database holds it: a
    render process decodes it itself, so the server's process never does)."""
    return render_plot(json.loads(result_json), name, fmt)
