"""Great-circle geometry on a spherical planet (pure math, shared by validation and the solver)."""

from __future__ import annotations

import math


def central_angle_rad(lat1_rad: float, lon1_rad: float, lat2_rad: float, lon2_rad: float) -> float:
    """Angle subtended at the planet's center by two surface points, by the haversine formula.

    hav(theta) = hav(dlat) + cos(lat1) cos(lat2) hav(dlon), hav(x) = sin^2(x/2)
    (R. W. Sinnott, "Virtues of the Haversine", Sky and Telescope 68(2), 1984); well
    conditioned for small separations, which is where zone-boundary checks happen.
    """
    sin_dlat = math.sin(0.5 * (lat2_rad - lat1_rad))
    sin_dlon = math.sin(0.5 * (lon2_rad - lon1_rad))
    h = sin_dlat * sin_dlat + math.cos(lat1_rad) * math.cos(lat2_rad) * sin_dlon * sin_dlon
    return 2.0 * math.asin(math.sqrt(min(1.0, max(0.0, h))))


def central_angle_deg(lat1_deg: float, lon1_deg: float, lat2_deg: float, lon2_deg: float) -> float:
    """Central angle, in degrees, between two points given by latitude and longitude in degrees."""
    return math.degrees(
        central_angle_rad(
            math.radians(lat1_deg),
            math.radians(lon1_deg),
            math.radians(lat2_deg),
            math.radians(lon2_deg),
        )
    )


def great_circle_distance_m(
    lat1_deg: float, lon1_deg: float, lat2_deg: float, lon2_deg: float, radius_m: float
) -> float:
    """Surface distance, in meters, between two points on a sphere of radius ``radius_m``."""
    angle = central_angle_rad(
        math.radians(lat1_deg),
        math.radians(lon1_deg),
        math.radians(lat2_deg),
        math.radians(lon2_deg),
    )
    return radius_m * angle
