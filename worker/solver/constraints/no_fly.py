"""No-fly-zone constraints linearized about the reference, and the node window of their penalty.

Distance to a zone is the great-circle central angle to its centre, the measure the verification
uses (paper 002 eq. 6 and 27 use the plane (lon, lat) distance instead, which is distorted by
cos(latitude) far from the equator). The central angle is convex near the zone, so its tangent
plane under-estimates it and the linearized exclusion c_bar + grad c . (x - x_bar) >= R is
conservative. The paper's distance penalty (sec. 3.3.2) is applied only to a window of nodes
around the reference's closest approach, so the nodes cluster there and not everywhere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from worker.solver.constraints.between_nodes import smooth_max_rows
from worker.solver.geometry import CircleZone
from worker.solver.transcription.foh_data import InnerRows
from worker.solver.transcription.foh_exact import IntervalSamples

Array = np.ndarray


@dataclass
class ZoneRows:
    """Central angle ``c`` (K,) from each node to the zone centre and its partials in lat, lon."""

    c: Array
    c_lat: Array
    c_lon: Array


def central_angle(lat: Array, lon: Array, zone: CircleZone) -> ZoneRows:
    """Haversine central angle to ``zone``'s centre with exact partials (rad, per rad)."""
    dlat = lat - zone.latitude
    dlon = lon - zone.longitude
    cz = np.cos(zone.latitude)
    sh = np.sin(0.5 * dlon)
    a = np.sin(0.5 * dlat) ** 2 + np.cos(lat) * cz * sh * sh
    a = np.clip(a, 1e-300, 1.0 - 1e-16)
    c = 2.0 * np.arcsin(np.sqrt(a))
    dc_da = 1.0 / np.sqrt(a * (1.0 - a))
    a_lat = 0.5 * np.sin(dlat) - np.sin(lat) * cz * sh * sh
    a_lon = 0.5 * np.cos(lat) * cz * np.sin(dlon)
    return ZoneRows(c=c, c_lat=dc_da * a_lat, c_lon=dc_da * a_lon)


def lat_lon_distance(lat: Array, lon: Array, zone: CircleZone) -> ZoneRows:
    """sqrt(dlat^2 + dlon^2) to ``zone``'s centre and its partials: paper 002's zone metric
    (eq. 27 linearizes its square), rad."""
    dlat = lat - zone.latitude
    dlon = lon - zone.longitude
    c = np.maximum(np.hypot(dlat, dlon), 1e-300)
    return ZoneRows(c=c, c_lat=dlat / c, c_lon=dlon / c)


def zone_distance(lat: Array, lon: Array, zone: CircleZone) -> ZoneRows:
    """Distance to ``zone``'s centre in the zone's metric, with partials (rad, per rad)."""
    if zone.metric == "lat_lon":
        return lat_lon_distance(lat, lon, zone)
    return central_angle(lat, lon, zone)


def longitude_factor(zone: CircleZone) -> float:
    """Weight of dlon against dlat in the zone's squared distance near its centre: cos(latitude)
    on the sphere, 1 in the lat_lon metric."""
    return math.cos(zone.latitude) if zone.metric == "great_circle" else 1.0


def penalty_window(clearance: Array, half_width: int) -> Array:
    """Boolean mask of the nodes within ``half_width`` of the smallest ``clearance``."""
    k = clearance.size
    i = int(np.argmin(clearance))
    mask = np.zeros(k, dtype=bool)
    mask[max(0, i - half_width) : min(k, i + half_width + 1)] = True
    return mask


def inner_zone_rows(
    zones: list[CircleZone],
    samples: IntervalSamples,
    width: float,
    *,
    exact: bool,
    margin: float = 0.0,
) -> InnerRows:
    """Zone exclusions between the nodes: R + margin - c <= 0 as the smooth maximum over each
    interval's samples (``width`` in rad of the zone's metric, ``exact``: value at the worst
    sample), linearized through the exact FOH maps (``between_nodes``), so a sparse grid cannot
    step over a zone between two nodes."""
    n, j = samples.x.shape[:2]
    lat = samples.x[..., 2].ravel()
    lon = samples.x[..., 1].ravel()
    g = np.empty((n * j, len(zones)))
    g_lat = np.empty_like(g)
    g_lon = np.empty_like(g)
    for i, zone in enumerate(zones):
        rows = zone_distance(lat, lon, zone)
        g[:, i] = zone.radius + margin - rows.c
        g_lat[:, i] = -rows.c_lat
        g_lon[:, i] = -rows.c_lon
    shape = (n, j, len(zones))
    return smooth_max_rows(
        g.reshape(shape),
        {2: g_lat.reshape(shape), 1: g_lon.reshape(shape)},
        samples,
        np.full(len(zones), width),
        exact=exact,
    )
