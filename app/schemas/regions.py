"""Circular regions on the planet's surface: no-fly zones to avoid and waypoints to overfly."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from app.schemas.base import FieldProblem, StrictModel, Text, raise_problems
from app.schemas.geometry import central_angle_rad


class _Circle(StrictModel):
    """A spherical cap given by its center and exactly one of a surface radius or angular radius."""

    radius_km: float | None = Field(
        None, gt=0, le=1e6, description="Radius along the surface, km; give this or radius_deg."
    )
    radius_deg: float | None = Field(
        None,
        gt=0,
        lt=180,
        description="Angular radius seen from the planet's center, deg; give this or radius_km.",
    )

    @model_validator(mode="after")
    def _one_radius(self) -> _Circle:
        if (self.radius_km is None) == (self.radius_deg is None):
            raise_problems(
                type(self).__name__,
                [
                    FieldProblem(
                        ("radius_km",),
                        "radius_spec",
                        "exactly one of radius_km and radius_deg must be given",
                        self.radius_km,
                    )
                ],
            )
        return self

    def radius_rad(self, planet_radius_m: float) -> float:
        """Angular radius of the region, rad, on a planet of radius ``planet_radius_m``."""
        if self.radius_deg is not None:
            return math.radians(self.radius_deg)
        assert self.radius_km is not None  # guaranteed by validation
        return self.radius_km * 1000.0 / planet_radius_m

    def center_deg(self) -> tuple[float, float]:
        """Latitude and longitude of the center, deg."""
        raise NotImplementedError

    def contains_point(
        self, latitude_deg: float, longitude_deg: float, planet_radius_m: float
    ) -> bool:
        """Whether a surface point is strictly inside the region (center distance < radius)."""
        lat, lon = self.center_deg()
        angle = central_angle_rad(
            math.radians(lat),
            math.radians(lon),
            math.radians(latitude_deg),
            math.radians(longitude_deg),
        )
        return angle < self.radius_rad(planet_radius_m)


class NoFlyZone(_Circle):
    """A circular zone the ground track must stay out of (an infinitely tall cylinder)."""

    name: Text | None = Field(None, max_length=200, description="Label of the zone.")
    center_latitude_deg: float = Field(
        ..., ge=-90, le=90, description="Latitude of the zone's center, deg."
    )
    center_longitude_deg: float = Field(
        ..., ge=-180, le=180, description="Longitude of the zone's center, deg."
    )

    def center_deg(self) -> tuple[float, float]:
        """Latitude and longitude of the center, deg."""
        return self.center_latitude_deg, self.center_longitude_deg

    metric: Literal["great_circle", "lat_lon"] = Field(
        "great_circle",
        description='How the distance to the center is measured: "great_circle", the central '
        'angle (a circle on the sphere); "lat_lon", sqrt(dlat^2 + dlon^2) in degrees of '
        "latitude and longitude, as in paper 002 eq. 27 (on the sphere an ellipse, narrower "
        "east-west by cos(latitude)).",
    )

    def contains_point(
        self, latitude_deg: float, longitude_deg: float, planet_radius_m: float
    ) -> bool:
        """Whether a surface point is strictly inside the zone, in the zone's own metric."""
        if self.metric == "great_circle":
            return super().contains_point(latitude_deg, longitude_deg, planet_radius_m)
        d = math.hypot(
            latitude_deg - self.center_latitude_deg, longitude_deg - self.center_longitude_deg
        )
        return math.radians(d) < self.radius_rad(planet_radius_m)


class Waypoint(_Circle):
    """A circular target region the ground track must pass through, in the given ``order``."""

    latitude_deg: float = Field(
        ..., ge=-90, le=90, description="Latitude of the waypoint's center, deg."
    )
    longitude_deg: float = Field(
        ..., ge=-180, le=180, description="Longitude of the waypoint's center, deg."
    )
    order: int = Field(
        ..., ge=0, description="Position in the visiting sequence (smaller first); unique."
    )

    def center_deg(self) -> tuple[float, float]:
        """Latitude and longitude of the center, deg."""
        return self.latitude_deg, self.longitude_deg
