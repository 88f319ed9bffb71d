"""Node placement in energy for energy-domain transcriptions.

Paper 000 uses a uniform grid in energy. Time per unit energy, dt/de = 1/(D V), varies by a
factor of ~4 along an entry (largest at the start, where the air is thin, and at the end, where
the vehicle is slow), so a uniform grid is coarsest exactly where the terminal maneuver happens.
The ``glide_time`` grid spaces nodes evenly in the time of an equilibrium glide,
dt/de ~ (L/D) / ((1 - V^2) V) with V^2 = 2 (1 - e), blended half-and-half with uniform spacing so
that no region is starved.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

BLEND = 1.0
GridKind = Literal["uniform", "glide_time"]


def energy_grid(e0: float, ef: float, nodes: int, kind: GridKind = "glide_time") -> np.ndarray:
    """``nodes`` increasing energies from ``e0`` to ``ef`` (both included)."""
    if kind == "uniform":
        return np.linspace(e0, ef, nodes)
    fine = np.linspace(e0, ef, 20 * nodes + 1)
    v2 = np.clip(2.0 * (1.0 - fine), 1e-4, 0.98)  # guard the ends of the formula's validity
    density = 1.0 / ((1.0 - v2) * np.sqrt(v2))
    density = BLEND * density / np.mean(density) + (1.0 - BLEND)
    cumulative = np.concatenate(
        [[0.0], np.cumsum(0.5 * (density[1:] + density[:-1]) * np.diff(fine))]
    )
    targets = np.linspace(0.0, cumulative[-1], nodes)
    grid = np.interp(targets, cumulative, fine)
    grid[0], grid[-1] = e0, ef
    return grid


def time_uniform_grid(e: np.ndarray, dt_de: np.ndarray, blend: float = 0.8) -> np.ndarray:
    """Energies with the same end points as ``e`` spaced evenly in flight time.

    ``dt_de`` is 1/(de/dt) at the nodes of ``e`` (from the current iterate); ``blend`` is the share
    of time-even spacing, the rest even in energy.
    """
    seconds = np.concatenate([[0.0], np.cumsum(0.5 * (dt_de[1:] + dt_de[:-1]) * np.diff(e))])
    measure = blend * seconds / seconds[-1] + (1.0 - blend) * (e - e[0]) / (e[-1] - e[0])
    grid = np.interp(np.linspace(0.0, 1.0, e.size), measure, e)
    grid[0], grid[-1] = e[0], e[-1]
    return grid
