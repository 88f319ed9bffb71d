"""Great circles on the unit sphere for the pre-checks: distances, bearings and the along- and
cross-track position of a point against a path's first leg (angles in radians)."""

from __future__ import annotations

import numpy as np

Array = np.ndarray


def central_angle(lat1: Array | float, lon1: Array | float, lat2: Array | float,
                  lon2: Array | float) -> Array:  # fmt: skip
    """The great-circle angle between two points (haversine)."""
    dlat = np.asarray(lat2) - lat1
    dlon = np.asarray(lon2) - lon1
    a = np.sin(0.5 * dlat) ** 2 + np.cos(lat1) * np.cos(lat2) * np.sin(0.5 * dlon) ** 2
    return 2.0 * np.arcsin(np.sqrt(np.clip(a, 0.0, 1.0)))


def bearing(lat1: float, lon1: float, lat2: Array | float, lon2: Array | float) -> Array:
    """The initial heading from the first point to the second, clockwise from north."""
    dlon = np.asarray(lon2) - lon1
    y = np.sin(dlon) * np.cos(lat2)
    x = np.cos(lat1) * np.sin(lat2) - np.sin(lat1) * np.cos(lat2) * np.cos(dlon)
    return np.arctan2(y, x)


def track_frame(lat0: float, lon0: float, heading: float, lat: Array | float,
                lon: Array | float) -> tuple[Array, Array]:  # fmt: skip
    """Along-track and cross-track angles of points against the great circle leaving
    (lat0, lon0) at ``heading``; cross-track positive to the right of the path."""
    d = central_angle(lat0, lon0, lat, lon)
    off = bearing(lat0, lon0, lat, lon) - heading
    cross = np.arcsin(np.clip(np.sin(d) * np.sin(off), -1.0, 1.0))
    along = np.arctan2(np.sin(d) * np.cos(off), np.cos(d))
    return along, cross
