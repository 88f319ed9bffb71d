"""h-refinement of a multi-interval CGL mesh from the solution's own error (paper 003 sec. 3).

Each interval's solution error is measured as paper 003 sec. 3.1 defines it: the states are
integrated through the nonlinear dynamics from the interval's first point, under the interval's
own attitude polynomial, to its end, and compared with the solution's last point there (Fig. 5's
e_k), in trust units. An interval is also marked where its polynomials leave a bound or a path
limit between its points by more than a tolerance (the peaks of paper 003 Fig. 10d lie between
points). Marked intervals are split at their middle (and at the peak of the violation when it
lies off-centre); the reference is carried onto the new mesh by its own polynomials.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np
from scipy.integrate import solve_ivp

from worker.solver.transcription.cgl import ChebyshevMesh

Array = np.ndarray
SAMPLES_PER_SEGMENT = 4
"""Fine-grid samples between consecutive points when checking bounds and limits."""


def fine_times(mesh: ChebyshevMesh, tf: float) -> tuple[Array, Array]:
    """Times of a fine grid over the span (``SAMPLES_PER_SEGMENT`` per gap between points) and
    the interval of each."""
    t_points = mesh.points(0.0, tf)
    edges = mesh.interval_times(0.0, tf)
    fine = []
    for a, b in itertools.pairwise(t_points):
        fine.append(np.linspace(a, b, SAMPLES_PER_SEGMENT + 1)[:-1])
    fine.append(t_points[-1:])
    t = np.concatenate(fine)
    which = np.clip(np.searchsorted(edges[1:-1], t, side="right"), 0, mesh.num_intervals - 1)
    return t, which


def interval_errors(
    mesh: ChebyshevMesh,
    tf: float,
    z: Array,
    rates: Callable[[Array, Array, Array], Array],
    attitude_at: Callable[[Array], Array],
    units: Array,
    n_flown: int,
) -> Array:
    """Largest scaled end-state error of each interval: the first ``n_flown`` states flown
    from the interval's first point under ``attitude_at(t)`` (the other states' values, e.g.
    bank and alpha, (M, 2) at M times) by ``rates(t, y, attitude)`` (vectorized: (M,) times,
    (M, n_flown) states) to its last point (paper 003 Fig. 5). All intervals are flown at once
    in a local variable s in [0, 1] (t = a_k + s h_k), one integration for the whole mesh."""
    edges = mesh.interval_times(0.0, tf)
    a, h = edges[:-1], np.diff(edges)
    slices = mesh.interval_slices()
    first = np.array([sl.start for sl in slices])
    last = np.array([sl.stop - 1 for sl in slices])
    n = mesh.num_intervals

    def f(s: float, flat: Array) -> Array:
        t = a + s * h
        y = flat.reshape(n, n_flown)
        return (h[:, None] * rates(t, y, attitude_at(t))).ravel()

    sol = solve_ivp(f, (0.0, 1.0), z[first, :n_flown].ravel(), rtol=1e-9, atol=1e-11)
    if not sol.success:
        return np.full(n, np.inf)
    end = sol.y[:, -1].reshape(n, n_flown)
    return np.max(np.abs(end - z[last, :n_flown]) / units[None, :n_flown], axis=1)


def split(mesh: ChebyshevMesh, marked: Array, peaks: Array, max_points: int) -> ChebyshevMesh:
    """The mesh with each marked interval split in two (at its middle, or at ``peaks[k]``, the
    fraction of its span where its violation peaks, when that lies in its middle 60 %), most
    marked first while the point count stays within ``max_points``."""
    bounds = list(mesh.boundaries)
    degrees = list(mesh.degrees)
    new_b: list[float] = [bounds[0]]
    new_d: list[int] = []
    budget = max_points - mesh.num_points
    for k in range(mesh.num_intervals):
        a, b = bounds[k], bounds[k + 1]
        if marked[k] and budget >= degrees[k]:
            frac = peaks[k] if np.isfinite(peaks[k]) and 0.2 <= peaks[k] <= 0.8 else 0.5
            new_b.append(a + frac * (b - a))
            new_d.extend([degrees[k], degrees[k]])
            budget -= degrees[k]
        else:
            new_d.append(degrees[k])
        new_b.append(b)
    return ChebyshevMesh(boundaries=tuple(new_b), degrees=tuple(new_d))


def carry(old: ChebyshevMesh, new: ChebyshevMesh, tf: float, values: Array) -> Array:
    """``values`` at the old mesh's points carried to the new mesh's points by the old mesh's
    piecewise polynomials."""
    return old.interpolate(values, 0.0, tf, new.points(0.0, tf))


def interval_fraction(mesh: ChebyshevMesh, k: int, t: float, tf: float) -> float:
    """Where ``t`` lies in interval ``k``, as a fraction of its span."""
    edges = mesh.interval_times(0.0, tf)
    return float((t - edges[k]) / (edges[k + 1] - edges[k]))


__all__ = [
    "carry",
    "fine_times",
    "interval_errors",
    "interval_fraction",
    "split",
]
