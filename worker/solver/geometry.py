"""Geometry shared by the problem model, the no-fly and waypoint rows and the verification.

A circle on the sphere is all the problem contract can ask for; it sits at the bottom of the core
so the constraint rows and the verification need not import the problem model for it.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class CircleZone:
    """A circular no-fly zone or waypoint on the sphere, angles in radians."""

    latitude: float
    longitude: float
    radius: float
    name: str | None = None
    order: int = 0
    metric: str = "great_circle"  # or "lat_lon": sqrt(dlat^2 + dlon^2) (paper 002 eq. 27)
