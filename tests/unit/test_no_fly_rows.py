"""Zone distances of the time-domain SCP and their partials, in both zone metrics.

The partials linearize the zone rows (paper 002 eq. 27); central differences with h = 1e-6 rad
carry errors near 1e-12 relative for these smooth functions away from the centre, so 1e-7 is a
loose bound that still catches any wrong term."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.schemas.geometry import central_angle_rad
from worker.solver.constraints.no_fly import zone_distance
from worker.solver.geometry import CircleZone

LAT = np.radians(np.array([40.0, 47.5, 52.0, 58.0]))
LON = np.radians(np.array([-3.0, 1.0, 9.0, 4.0]))


@pytest.mark.parametrize("metric", ["great_circle", "lat_lon"])
def test_partials_match_central_differences(metric: str) -> None:
    zone = CircleZone(math.radians(50.0), math.radians(5.0), math.radians(5.5), metric=metric)
    rows = zone_distance(LAT, LON, zone)
    h = 1e-6
    d_lat = (zone_distance(LAT + h, LON, zone).c - zone_distance(LAT - h, LON, zone).c) / (2 * h)
    d_lon = (zone_distance(LAT, LON + h, zone).c - zone_distance(LAT, LON - h, zone).c) / (2 * h)
    np.testing.assert_allclose(rows.c_lat, d_lat, rtol=1e-7)
    np.testing.assert_allclose(rows.c_lon, d_lon, rtol=1e-7)


def test_metrics_measure_what_they_say() -> None:
    centre = (math.radians(50.0), math.radians(5.0))
    sphere = CircleZone(*centre, 0.1)
    plane = CircleZone(*centre, 0.1, metric="lat_lon")
    for lat, lon in zip(LAT, LON, strict=True):
        great = central_angle_rad(lat, lon, *centre)
        # Same haversine formula, vectorized: rounding only.
        assert zone_distance(np.array([lat]), np.array([lon]), sphere).c[0] == pytest.approx(
            great, rel=1e-12
        )
        flat = math.hypot(lat - centre[0], lon - centre[1])
        assert zone_distance(np.array([lat]), np.array([lon]), plane).c[0] == pytest.approx(
            flat, rel=1e-15
        )
