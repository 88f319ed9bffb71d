"""The multi-interval CGL mesh of the Chebyshev SCvx: legs between waypoints, each cut into
intervals with one polynomial each.

Interval s has its own degree n_s and duration T_s; the intervals of a leg share the leg's free
duration equally, and each leg's duration is free (the time of arrival at its waypoint).
Neighbouring intervals share their joint's state but not its control, so one interval is paper
001's single Chebyshev interval (eq. 36) and the flight without waypoints one leg. Points are
numbered along the flight: the state points (sum n_s + 1) and the control points (sum (n_s + 1),
each interval its own ends).
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from worker.solver.transcription.cgl import (
    barycentric_weights,
    cgl_points,
    clenshaw_curtis_weights,
    differentiation_matrix,
    integration_matrix,
    interpolate,
)

Array = np.ndarray
RATE_SAMPLES_PER_GAP = 9
"""Samples of the bank's rate in each gap between neighbouring points (its rows enter only
where the rate nears its limit): the rate, a ratio of the lift polynomials' derivatives, peaks
between the points, where the zones' 3 samples a gap can miss it beyond the verification's 1 %
(docs/methods/README.md, "User-problem suite")."""


@dataclass(frozen=True)
class Segments:
    """Degrees of the intervals, the leg (waypoint to waypoint) of each, and the maps between
    their points and the flight's. The intervals of one leg share its duration equally."""

    degrees: tuple[int, ...]
    samples_per_gap: int = 3
    legs: tuple[int, ...] = ()

    @staticmethod
    def sized(points: int, intervals: int, lengths: list[float], samples_per_gap: int) -> Segments:
        """``points`` CGL points and ``intervals`` intervals shared among the legs in proportion
        to their ``lengths`` (at least one interval of degree 2 per leg)."""
        total = sum(lengths) or 1.0
        degrees: list[int] = []
        legs: list[int] = []
        for leg, length in enumerate(lengths):
            share = length / total if len(lengths) > 1 else 1.0
            k = max(1, round(intervals * share))
            leg_degree = max(2 * k, round((points - 1) * share))
            base, extra = divmod(leg_degree, k)
            degrees += [base + (1 if i < extra else 0) for i in range(k)]
            legs += [leg] * k
        return Segments(tuple(degrees), samples_per_gap, tuple(legs))

    def __post_init__(self) -> None:
        """One leg when none is given."""
        if not self.legs:
            object.__setattr__(self, "legs", (0,) * len(self.degrees))

    @cached_property
    def leg_count(self) -> int:
        """Number of legs (waypoints + 1)."""
        return max(self.legs) + 1

    def leg_intervals(self, leg: int) -> Array:
        """The intervals of ``leg``."""
        return np.flatnonzero(np.asarray(self.legs) == leg)

    @property
    def count(self) -> int:
        """Number of segments."""
        return len(self.degrees)

    @cached_property
    def state_points(self) -> int:
        """Distinct state points of the flight."""
        return sum(self.degrees) + 1

    @cached_property
    def control_points(self) -> int:
        """Control points (each segment its own ends)."""
        return sum(n + 1 for n in self.degrees)

    @cached_property
    def first_state(self) -> Array:
        """Index of each segment's first state point, and past the last one's end (count + 1)."""
        return np.concatenate([[0], np.cumsum(self.degrees)]).astype(np.int64)

    @cached_property
    def state_of_control(self) -> Array:
        """State point of every control point (control points are segment-major)."""
        return np.concatenate(
            [self.first_state[s] + np.arange(n + 1) for s, n in enumerate(self.degrees)]
        )

    @cached_property
    def segment_of_control(self) -> Array:
        """Segment of every control point."""
        return np.repeat(np.arange(self.count), [n + 1 for n in self.degrees])

    @cached_property
    def joints(self) -> Array:
        """State points at the leg joints (the waypoint passages), in order."""
        legs = np.asarray(self.legs)
        return self.first_state[1:-1][legs[1:] != legs[:-1]]

    def durations(self, leg_durations: Array) -> Array:
        """Each interval's duration: its leg's shared equally among the leg's intervals."""
        legs = np.asarray(self.legs)
        counts = np.bincount(legs, minlength=self.leg_count)
        return np.asarray(leg_durations)[legs] / counts[legs]

    def differentiation(self, s: int) -> Array:
        """Segment ``s``'s CGL differentiation matrix on [-1, 1] (paper 001 eq. 23)."""
        return differentiation_matrix(self.degrees[s])

    def integration(self, s: int) -> Array:
        """Segment ``s``'s CGL integration matrix on [-1, 1] (row i integrates from -1 to tau_i)."""
        return integration_matrix(self.degrees[s])

    def quadrature(self, s: int) -> Array:
        """Segment ``s``'s Clenshaw-Curtis weights on [-1, 1]."""
        return clenshaw_curtis_weights(self.degrees[s])

    def tau(self, s: int) -> Array:
        """Segment ``s``'s CGL points on [-1, 1]."""
        return cgl_points(self.degrees[s])

    @cached_property
    def between(self) -> list[tuple[Array, Array]]:
        """Per segment, the samples between neighbouring points: (tau of each sample, the
        interpolation weights (samples, n_s + 1) that give a sample from the segment's points)."""
        return [self._samples(n, self.samples_per_gap) for n in self.degrees]

    def _samples(self, n: int, per_gap: int) -> tuple[Array, Array]:
        """``per_gap`` evenly spaced samples in each gap of a degree-``n`` segment's points:
        their tau and interpolation weights."""
        tau = cgl_points(n)
        if per_gap < 1:
            return np.zeros(0), np.zeros((0, n + 1))
        frac = np.arange(1, per_gap + 1) / (per_gap + 1)
        samples = (tau[:-1, None] + np.diff(tau)[:, None] * frac[None, :]).ravel()
        return samples, interpolate(np.eye(n + 1), n, samples)

    @cached_property
    def rate_between(self) -> list[tuple[Array, Array]]:
        """Per segment, the bank rate's samples between neighbouring points, as ``between``
        but ``RATE_SAMPLES_PER_GAP`` in each gap."""
        return [self._samples(n, RATE_SAMPLES_PER_GAP) for n in self.degrees]

    @cached_property
    def rate_evaluation(self) -> list[tuple[Array, Array]]:
        """Per segment, where its bank rate is checked: (E, F), each (n_s + 1 + samples,
        n_s + 1), giving the control polynomial's values (E) and tau-derivatives (F) at the
        points followed by the ``rate_between`` samples."""
        out = []
        for s, (_, w) in enumerate(self.rate_between):
            d = self.differentiation(s)
            eye = np.eye(d.shape[0])
            out.append((np.vstack([eye, w]), np.vstack([d, w @ d])))
        return out

    @cached_property
    def rate_rows(self) -> int:
        """Number of places the bank rate is checked (points and between samples)."""
        return sum(e.shape[0] for e, _ in self.rate_evaluation)

    @cached_property
    def between_rows(self) -> list[tuple[Array, Array]]:
        """Per between sample (segment-major), its segment's state points and interpolation
        weights: the rows that give the samples from the points."""
        out: list[tuple[Array, Array]] = []
        for s, (_, w) in enumerate(self.between):
            states = np.arange(self.state_points)[self.states_of(s)]
            out.extend((states, row) for row in w)
        return out

    def times(self, durations: Array) -> Array:
        """Time of every state point from the start, given the segments' durations."""
        start = np.concatenate([[0.0], np.cumsum(durations)])
        parts = [start[0:1]]
        for s, n in enumerate(self.degrees):
            tau = cgl_points(n)
            parts.append(start[s] + 0.5 * (tau[1:] + 1.0) * durations[s])
        return np.concatenate(parts)

    def control_times(self, durations: Array) -> Array:
        """Time of every control point from the start."""
        start = np.concatenate([[0.0], np.cumsum(durations)])
        return np.concatenate(
            [
                start[s] + 0.5 * (cgl_points(n) + 1.0) * durations[s]
                for s, n in enumerate(self.degrees)
            ]
        )

    def states_of(self, s: int) -> slice:
        """Slice of segment ``s``'s state points."""
        return slice(int(self.first_state[s]), int(self.first_state[s + 1]) + 1)

    def controls_of(self, s: int) -> slice:
        """Slice of segment ``s``'s control points."""
        start = sum(n + 1 for n in self.degrees[:s])
        return slice(start, start + self.degrees[s] + 1)


@dataclass(frozen=True)
class LiftVectorPath:
    """Bank and normalized lift between the points as the method represents them: u1 and u2 as
    each interval's interpolating polynomial (the collocation integrates the polynomial through
    the points' rates), sigma = atan2(u2, u1) and lam = |(u1, u2)| saturated to the bank and lift
    ranges as a vehicle's command would be (``trajectory.AttitudePath``; lam in the angle of
    attack's place, see ``aero_models``). Rates are the polynomials' exact derivatives."""

    segments: Segments
    durations: Array  # (S,) nondimensional
    u: Array  # (control points, 3)
    bank_range: tuple[float, float] = (-math.pi, math.pi)
    lift_range: tuple[float, float] = (0.0, math.inf)
    alpha_deg: Array | None = None
    """The angle of attack at the control points of a vehicle flown by its lift share: flown
    (in lam's place) as each interval's interpolating polynomial, within ``alpha_range``."""
    alpha_range: tuple[float, float] | None = None

    @property
    def breaks(self) -> Array:
        """Times where the intervals' polynomials meet (the path is smooth in between): the
        verification restarts its integration there only."""
        return np.cumsum(self.durations)[:-1]

    def _interpolated(self, points: Array, t: Array, derivative: bool) -> Array:
        """Each interval's polynomial through ``points`` (control points, k) at times ``t``."""
        start = np.concatenate([[0.0], np.cumsum(self.durations)])
        flat = np.clip(np.asarray(t, dtype=float).reshape(-1), 0.0, start[-1])
        last = self.segments.count - 1
        which = np.clip(np.searchsorted(start[1:-1], flat, side="right"), 0, last)
        values = np.empty((flat.size, points.shape[1]))
        for s in np.unique(which).tolist():  # one interval for the integrator's single times
            mask = which == s
            u = points[self.segments.controls_of(s)]
            tau = np.clip(2.0 * (flat[mask] - start[s]) / self.durations[s] - 1.0, -1.0, 1.0)
            if derivative:
                u = self.segments.differentiation(s) @ u * (2.0 / self.durations[s])
            values[mask] = interpolate(u, self.segments.degrees[s], tau)
        return values

    def _uv(self, t: Array, derivative: bool) -> tuple[Array, Array]:
        values = self._interpolated(self.u[:, :2], t, derivative)
        return values[:, 0], values[:, 1]

    @cached_property
    def _scalar_tables(self) -> tuple[list[float], list[float], list[tuple[list[float], ...]]]:
        """For one time at a time (the integrator's calls): the interior breaks, the starts and
        per interval its CGL points, barycentric weights and the values (u1, u2[, alpha]) at
        its points, as Python floats."""
        start = np.concatenate([[0.0], np.cumsum(self.durations)])
        columns = [self.u[:, 0], self.u[:, 1]]
        if self.alpha_deg is not None:
            columns.append(self.alpha_deg)
        tables = []
        for s, n in enumerate(self.segments.degrees):
            ctrl = self.segments.controls_of(s)
            tables.append(
                (
                    self.segments.tau(s).tolist(),
                    barycentric_weights(n).tolist(),
                    *(c[ctrl].tolist() for c in columns),
                )
            )
        return start[1:-1].tolist(), start.tolist(), tables

    def _at_scalar(self, t: float) -> tuple[float, float]:
        """``at`` for one time in Python floats: the same barycentric interpolation (second
        kind, a node's own value on a node) without the array machinery, for the integrator's
        right-hand side."""
        breaks, start, tables = self._scalar_tables
        t = min(max(t, 0.0), start[-1])
        s = bisect_right(breaks, t)
        tau = min(max(2.0 * (t - start[s]) / (start[s + 1] - start[s]) - 1.0, -1.0), 1.0)
        x, w, *cols = tables[s]
        out = [0.0] * len(cols)
        den = 0.0
        for j, xj in enumerate(x):
            d = tau - xj
            if d == 0.0:
                out = [c[j] for c in cols]
                den = 1.0
                break
            c_j = w[j] / d
            den += c_j
            for i, col in enumerate(cols):
                out[i] += c_j * col[j]
        u1, u2 = out[0] / den, out[1] / den
        bank = min(max(math.atan2(u2, u1), self.bank_range[0]), self.bank_range[1])
        if self.alpha_deg is not None:
            assert self.alpha_range is not None
            return bank, min(max(out[2] / den, self.alpha_range[0]), self.alpha_range[1])
        return bank, min(max(math.hypot(u1, u2), self.lift_range[0]), self.lift_range[1])

    def at(self, t: Array) -> tuple[Array, Array]:
        """(bank rad, lam) at nondimensional times ``t``; (bank, alpha deg) for a lift share."""
        shape = np.shape(t)
        if np.size(t) == 1:  # the integrator's one time: Python floats
            bank, second = self._at_scalar(float(np.asarray(t, dtype=float).reshape(-1)[0]))
            return np.full(shape, bank), np.full(shape, second)
        u1, u2 = self._uv(t, False)
        bank = np.clip(np.arctan2(u2, u1), *self.bank_range)
        if self.alpha_deg is not None:
            assert self.alpha_range is not None
            alpha = self._interpolated(self.alpha_deg[:, None], t, False)[:, 0]
            return bank.reshape(shape), np.clip(alpha, *self.alpha_range).reshape(shape)
        lam = np.clip(np.hypot(u1, u2), *self.lift_range)
        return bank.reshape(shape), lam.reshape(shape)

    def rates_at(self, t: Array) -> tuple[Array, Array]:
        """(d sigma/dt, d lam/dt) at times ``t`` (per nondimensional time), unsaturated; for a
        lift share (d sigma/dt, d alpha/dt in radians)."""
        shape = np.shape(t)
        u1, u2 = self._uv(t, False)
        d1, d2 = self._uv(t, True)
        q = np.maximum(u1 * u1 + u2 * u2, 1e-300)
        bank_rate = ((u1 * d2 - u2 * d1) / q).reshape(shape)
        if self.alpha_deg is not None:
            alpha_rate = np.radians(self._interpolated(self.alpha_deg[:, None], t, True)[:, 0])
            return bank_rate, alpha_rate.reshape(shape)
        lam = np.sqrt(q)
        return bank_rate, ((u1 * d1 + u2 * d2) / lam).reshape(shape)
