"""Caps of the problem contract: sizes a single request may ask for, kept in one place."""

from __future__ import annotations

from typing import Final

MAX_NO_FLY_ZONES: Final[int] = 20
"""Most no-fly zones one problem may declare."""

MAX_WAYPOINTS: Final[int] = 20
"""Most waypoints one problem may declare."""

MAX_PHASES: Final[int] = 5
"""Most phases one problem may declare."""

MAX_NODES: Final[int] = 2000
"""Most discretization nodes a method may be asked for."""

MAX_ITERATIONS: Final[int] = 500
"""Most sequential convex programming iterations a method may be asked for."""

MAX_TIME_LIMIT_S: Final[float] = 3600.0
"""Longest wall-clock time limit, in seconds, a method may be given."""

MAX_POLYNOMIAL_COEFFICIENTS: Final[int] = 8
"""Most coefficients of an aerodynamic polynomial (degree 7)."""

MAX_OBJECTIVE_TERMS: Final[int] = 8
"""Most terms of a weighted objective."""

MAX_TABLE_POINTS: Final[int] = 200
"""Most breakpoints along one axis of a tabulated function."""
