"""Chebyshev–Gauss–Lobatto (CGL) discretization: points, differentiation, quadrature, integration,
interpolation, and a multi-interval mesh built from them.

The shared building block of the Chebyshev pseudospectral methods (single-interval SCvx and the
hp-adaptive multi-interval SCP): a single interval is a ``ChebyshevMesh`` with one interval. The
per-degree base operators on [-1, 1] are cached and returned read-only. Points are in increasing
order, tau_j = -cos(pi j / n), j = 0..n, so that the first point is the start of an interval.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

SPAN_RTOL = 1e-12  # relative slack when checking that a point lies in its span (roundoff only)


def _check_degree(n: int) -> int:
    """``n`` as an int, or ValueError unless it is an integer >= 1."""
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
        raise ValueError(f"the polynomial degree must be an integer >= 1, got {n!r}")
    return int(n)


def _read_only(a: FloatArray) -> FloatArray:
    a.setflags(write=False)
    return a


@lru_cache(maxsize=128)
def _cgl_points(n: int) -> FloatArray:
    # -cos(pi j / n) written as sin(pi (2j - n) / (2n)): exactly symmetric, exact 0 at the middle
    j = np.arange(n + 1)
    return _read_only(np.sin(np.pi * (2 * j - n) / (2 * n)))


def cgl_points(n: int) -> FloatArray:
    """The n + 1 CGL points tau_j = -cos(pi j / n) on [-1, 1], increasing (n >= 1)."""
    return _cgl_points(_check_degree(n))


@lru_cache(maxsize=128)
def _barycentric_weights(n: int) -> FloatArray:
    w = np.where(np.arange(n + 1) % 2 == 0, 1.0, -1.0)
    w[0] *= 0.5
    w[-1] *= 0.5
    return _read_only(w)


def barycentric_weights(n: int) -> FloatArray:
    """Barycentric weights of the CGL points, (-1)^j with the two end weights halved
    (Berrut & Trefethen (2004), "Barycentric Lagrange interpolation", SIAM Rev. 46, sec. 5);
    any common factor cancels in the interpolation formula."""
    return _barycentric_weights(_check_degree(n))


@lru_cache(maxsize=128)
def _differentiation_matrix(n: int) -> FloatArray:
    i = np.arange(n + 1)
    # tau_i - tau_j = cos(pi j/n) - cos(pi i/n) = 2 sin(pi (i+j)/(2n)) sin(pi (i-j)/(2n)):
    # the trigonometric form avoids cancellation between close points near the ends
    diff = 2.0 * np.sin(np.pi * (i[:, None] + i[None, :]) / (2 * n))
    diff *= np.sin(np.pi * (i[:, None] - i[None, :]) / (2 * n))
    np.fill_diagonal(diff, 1.0)
    w = _barycentric_weights(n)
    D = (w[None, :] / w[:, None]) / diff
    np.fill_diagonal(D, 0.0)
    # negative-sum trick: each row annihilates constants exactly, far more accurate than the
    # closed-form diagonal (Baltensperger & Trummer (2003), SIAM J. Sci. Comput. 24)
    np.fill_diagonal(D, -D.sum(axis=1))
    return _read_only(D)


def differentiation_matrix(n: int) -> FloatArray:
    """(n+1, n+1) CGL differentiation matrix: (D f)(tau_i) = f'(tau_i) exactly for polynomials of
    degree <= n (Trefethen, Spectral Methods in MATLAB (2000), ch. 6, in increasing order:
    D_ij = (w_j / w_i) / (tau_i - tau_j) off the diagonal, diagonal = minus the row sum)."""
    return _differentiation_matrix(_check_degree(n))


@lru_cache(maxsize=128)
def _clenshaw_curtis_weights(n: int) -> FloatArray:
    # w_j = (c_j / n) [1 - sum_{k=1}^{n/2} b_k cos(2 k theta_j) / (4 k^2 - 1)], theta_j = pi j / n,
    # c_j = 1 at the ends and 2 inside, b_k = 1 for k = n/2 and 2 otherwise (Waldvogel (2006),
    # BIT 46; Trefethen (2008), SIAM Rev. 50, sec. 2). Symmetric, so the order of the
    # points does not matter.
    j = np.arange(n + 1)
    k = np.arange(1, n // 2 + 1)
    b = np.full(k.size, 2.0)
    if n % 2 == 0:
        b[-1] = 1.0
    theta = np.pi * j / n
    terms = (b / (4.0 * k**2 - 1.0))[None, :] * np.cos(2.0 * k[None, :] * theta[:, None])
    c = np.full(n + 1, 2.0)
    c[0] = c[-1] = 1.0
    return _read_only(c / n * (1.0 - terms.sum(axis=1)))


def clenshaw_curtis_weights(n: int) -> FloatArray:
    """Clenshaw–Curtis weights on the n + 1 CGL points: sum_j w_j f(tau_j) = int_{-1}^{1} f exactly
    for polynomials of degree <= n; they sum to 2 (Waldvogel (2006), Trefethen (2008))."""
    return _clenshaw_curtis_weights(_check_degree(n))


@lru_cache(maxsize=128)
def _integration_matrix(n: int) -> FloatArray:
    # T_k(tau_j) = T_k(-cos(theta_j)) = (-1)^k cos(k theta_j), theta_j = pi j / n; the product
    # k j is reduced mod 2n so the cosine is evaluated at a small argument
    j = np.arange(n + 1)
    k = np.arange(n + 2)
    T = ((-1.0) ** k)[:, None] * np.cos(np.pi * ((k[:, None] * j[None, :]) % (2 * n)) / n)
    # values -> Chebyshev coefficients (discrete cosine transform of type I on the CGL points):
    # a_k = (2 / (n c_k)) sum_j'' f_j T_k(tau_j), '' halving the two end terms, c_0 = c_n = 2
    half = np.ones(n + 1)
    half[0] = half[-1] = 0.5
    ck = np.ones(n + 1)
    ck[0] = ck[-1] = 2.0
    to_coef = (2.0 / n) * (half[None, :] * T[: n + 1]) / ck[:, None]
    # coefficients of an antiderivative (degree n + 1): int T_0 = T_1, int T_1 = T_2 / 4,
    # int T_k = T_{k+1} / (2 (k+1)) - T_{k-1} / (2 (k-1)) for k >= 2
    anti = np.zeros((n + 2, n + 1))
    anti[1, 0] = 1.0
    anti[2, 1] = 0.25
    for m in range(2, n + 1):
        anti[m + 1, m] = 1.0 / (2 * (m + 1))
        anti[m - 1, m] = -1.0 / (2 * (m - 1))
    # value at tau_i minus the value at tau_0 = -1: int_{-1}^{tau_i} of the interpolant
    B = (T - T[:, :1]).T @ anti @ to_coef
    return _read_only(B)


def integration_matrix(n: int) -> FloatArray:
    """(n+1, n+1) spectral integration matrix: (B f')(tau_i) = f(tau_i) - f(-1) exactly for
    polynomials f of degree <= n. Row i integrates the interpolant of the values from -1 to tau_i
    through its Chebyshev expansion (Greengard (1991), SIAM J. Numer. Anal. 28; the last row equals
    the Clenshaw–Curtis weights)."""
    return _integration_matrix(_check_degree(n))


def interpolate(values: ArrayLike, n: int, tau: ArrayLike) -> FloatArray:
    """Degree-n interpolant through ``values`` at the CGL points, evaluated at ``tau`` in [-1, 1]
    by the barycentric formula of the second kind (Berrut & Trefethen (2004), sec. 4); points that
    coincide with a node return its value exactly. ``values`` is (n+1,) or (n+1, k); the result has
    shape ``tau.shape + values.shape[1:]``."""
    n = _check_degree(n)
    f = np.asarray(values, dtype=float)
    if f.ndim not in (1, 2) or f.shape[0] != n + 1:
        raise ValueError(f"values must have shape ({n + 1},) or ({n + 1}, k), got {f.shape}")
    t = np.asarray(tau, dtype=float)
    if not np.all(np.isfinite(t)) or np.any(np.abs(t) > 1.0 + SPAN_RTOL):
        raise ValueError("interpolation points must be finite and lie in [-1, 1]")
    x = _cgl_points(n)
    w = _barycentric_weights(n)
    flat = t.reshape(-1)
    f2 = f.reshape(n + 1, -1)
    diff = flat[:, None] - x[None, :]
    exact = diff == 0.0
    hit = exact.any(axis=1)
    p = np.empty((flat.size, f2.shape[1]))
    p[hit] = f2[np.argmax(exact[hit], axis=1)]  # at a node: its value, no arithmetic
    c = w[None, :] / diff[~hit]
    p[~hit] = (c @ f2) / c.sum(axis=1)[:, None]
    return p.reshape(t.shape + f.shape[1:])


@dataclass(frozen=True)
class ChebyshevMesh:
    """Multi-interval CGL mesh on a time span [t0, tf]: interval k covers the fractions
    [boundaries[k], boundaries[k+1]] of the span with a degree-``degrees[k]`` polynomial.

    Adjacent intervals share their boundary point, so the mesh has sum(degrees) + 1 distinct
    points, numbered globally in increasing time.
    """

    boundaries: tuple[float, ...]
    degrees: tuple[int, ...]

    def __post_init__(self) -> None:
        bounds = tuple(float(b) for b in self.boundaries)
        degrees = tuple(self.degrees)
        if len(bounds) < 2:
            raise ValueError("boundaries must have at least two entries (0 and 1)")
        if not all(math.isfinite(b) for b in bounds):
            raise ValueError(f"boundaries must be finite, got {bounds}")
        if bounds[0] != 0.0 or bounds[-1] != 1.0:
            raise ValueError(f"boundaries must start at 0 and end at 1, got {bounds}")
        if any(b <= a for a, b in itertools.pairwise(bounds)):
            raise ValueError(f"boundaries must be strictly increasing, got {bounds}")
        if len(degrees) != len(bounds) - 1:
            raise ValueError(
                f"one degree per interval: {len(bounds) - 1} intervals, {len(degrees)} degrees"
            )
        for d in degrees:
            if isinstance(d, bool) or not isinstance(d, int | np.integer) or d < 1:
                raise ValueError(f"every degree must be an integer >= 1, got {degrees}")
        object.__setattr__(self, "boundaries", bounds)
        object.__setattr__(self, "degrees", tuple(int(d) for d in degrees))

    @classmethod
    def uniform(cls, intervals: int, degree: int) -> ChebyshevMesh:
        """``intervals`` equal intervals, each of polynomial degree ``degree``."""
        if isinstance(intervals, bool) or not isinstance(intervals, int) or intervals < 1:
            raise ValueError(f"the number of intervals must be an integer >= 1, got {intervals!r}")
        bounds = tuple(float(b) for b in np.linspace(0.0, 1.0, intervals + 1))
        return cls(boundaries=bounds, degrees=(degree,) * intervals)

    @property
    def num_intervals(self) -> int:
        """Number of intervals."""
        return len(self.degrees)

    @property
    def num_points(self) -> int:
        """Number of distinct points: sum(degrees) + 1 (shared boundaries counted once)."""
        return sum(self.degrees) + 1

    def interval_slices(self) -> list[slice]:
        """Global index range of each interval's n_k + 1 points; consecutive slices overlap by
        one index, the shared boundary point."""
        slices = []
        start = 0
        for n in self.degrees:
            slices.append(slice(start, start + n + 1))
            start += n
        return slices

    def interval_times(self, t0: float, tf: float) -> FloatArray:
        """Global times of the num_intervals + 1 interval boundaries on [t0, tf]."""
        _check_span(t0, tf)
        frac = np.asarray(self.boundaries)
        return t0 * (1.0 - frac) + tf * frac  # exactly t0 and tf at the ends

    def points(self, t0: float, tf: float) -> FloatArray:
        """Global times of all num_points distinct points on [t0, tf], increasing."""
        edges = self.interval_times(t0, tf)
        t = np.empty(self.num_points)
        for k, (n, sl) in enumerate(zip(self.degrees, self.interval_slices(), strict=True)):
            tau = _cgl_points(n)
            # (a (1 - tau) + b (1 + tau)) / 2 is exactly a and b at tau = -1, 1
            t[sl] = 0.5 * (edges[k] * (1.0 - tau) + edges[k + 1] * (1.0 + tau))
        return t

    def differentiation_matrices(self, t0: float, tf: float) -> list[FloatArray]:
        """Per-interval (n_k+1, n_k+1) matrices of d/dt on [t0, tf]: (2 / h_k) D_{n_k}, h_k the
        interval's length in time (d/dt = (2 / h_k) d/dtau)."""
        h = np.diff(self.interval_times(t0, tf))
        return [
            (2.0 / hk) * _differentiation_matrix(n) for hk, n in zip(h, self.degrees, strict=True)
        ]

    def quadrature_weights(self, t0: float, tf: float) -> FloatArray:
        """Composite Clenshaw–Curtis weights over the global points: sum(w * f(points)) is the
        integral over [t0, tf], exact for polynomials of degree <= min(degrees) (and for
        piecewise polynomials of degree <= n_k on each interval). Each interval's weights are
        scaled by h_k / 2 and summed at shared points."""
        h = np.diff(self.interval_times(t0, tf))
        w = np.zeros(self.num_points)
        for hk, n, sl in zip(h, self.degrees, self.interval_slices(), strict=True):
            w[sl] += 0.5 * hk * _clenshaw_curtis_weights(n)
        return w

    def interpolate(self, values: ArrayLike, t0: float, tf: float, t: ArrayLike) -> FloatArray:
        """The piecewise polynomial through ``values`` at the global points, evaluated at times
        ``t`` in [t0, tf], each with its own interval's interpolant (at a shared boundary both
        agree). ``values`` is (num_points,) or (num_points, k); the result has shape
        ``t.shape + values.shape[1:]``."""
        f = np.asarray(values, dtype=float)
        if f.ndim not in (1, 2) or f.shape[0] != self.num_points:
            raise ValueError(
                f"values must have shape ({self.num_points},) or ({self.num_points}, k), "
                f"got {f.shape}"
            )
        tt = np.asarray(t, dtype=float)
        edges = self.interval_times(t0, tf)
        slack = SPAN_RTOL * (tf - t0)
        flat = tt.reshape(-1)
        if not np.all(np.isfinite(flat)) or np.any(flat < t0 - slack) or np.any(flat > tf + slack):
            raise ValueError(f"interpolation times must be finite and lie in [{t0}, {tf}]")
        which = np.searchsorted(edges[1:-1], flat, side="right")
        out = np.empty((flat.size, *f.shape[1:]))
        for k, (n, sl) in enumerate(zip(self.degrees, self.interval_slices(), strict=True)):
            mask = which == k
            if not np.any(mask):
                continue
            a, b = edges[k], edges[k + 1]
            tau = np.clip((2.0 * flat[mask] - a - b) / (b - a), -1.0, 1.0)
            out[mask] = interpolate(f[sl], n, tau)
        return out.reshape(tt.shape + f.shape[1:])


def _check_span(t0: float, tf: float) -> None:
    """ValueError unless t0 < tf, both finite."""
    if not (math.isfinite(t0) and math.isfinite(tf) and tf > t0):
        raise ValueError(f"the time span must be finite with tf > t0, got [{t0}, {tf}]")
