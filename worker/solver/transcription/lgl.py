"""Legendre–Gauss–Lobatto (LGL) collocation: points, quadrature weights, differentiation and
integration matrices, interpolation, and a multi-segment mesh of one phase.

Paper 004 transcribes its phases by LGL collocation. Here a phase is cut into segments, each
with the n + 1 LGL points of degree n on [-1, 1] (both ends included, so neighbouring segments
share their end point), and the dynamics are collocated in integral form: the state at each
point of a segment equals the segment's first state plus the integral of the degree-n
interpolant of the rates, x_j = x_0 + (h/2) sum_l A_jl f_l (A = ``integration_matrix``). That is
the Lobatto IIIA collocation scheme (Hairer, Norsett & Wanner, Solving ODEs I, sec. II.7): n
equations per state and segment for the n new points, well posed where the differential form
D x = f at all n + 1 points is not (D annihilates constants).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np
from numpy.polynomial import legendre
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def _check_degree(n: int) -> int:
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
        raise ValueError(f"the LGL degree must be an integer >= 1, got {n!r}")
    return int(n)


def _read_only(a: FloatArray) -> FloatArray:
    a.setflags(write=False)
    return a


@lru_cache(maxsize=64)
def _points(n: int) -> FloatArray:
    # interior points: the roots of P_n'(x), refined by Newton on the companion-matrix guess
    if n == 1:
        return _read_only(np.array([-1.0, 1.0]))
    coef = np.zeros(n + 1)
    coef[n] = 1.0
    dcoef = legendre.legder(coef)
    x = np.sort(legendre.legroots(dcoef).real)
    d2coef = legendre.legder(dcoef)
    for _ in range(3):
        x = x - legendre.legval(x, dcoef) / legendre.legval(x, d2coef)
    x = 0.5 * (x - x[::-1])  # exactly symmetric
    return _read_only(np.concatenate([[-1.0], x, [1.0]]))


def lgl_points(n: int) -> FloatArray:
    """The n + 1 LGL points on [-1, 1], increasing: -1, the roots of P_n', 1 (n >= 1)."""
    return _points(_check_degree(n))


@lru_cache(maxsize=64)
def _weights(n: int) -> FloatArray:
    x = _points(n)
    coef = np.zeros(n + 1)
    coef[n] = 1.0
    p = legendre.legval(x, coef)
    return _read_only(2.0 / (n * (n + 1) * p * p))


def lgl_weights(n: int) -> FloatArray:
    """LGL quadrature weights w_j = 2 / (n (n + 1) P_n(x_j)^2): exact for degree 2n - 1."""
    return _weights(_check_degree(n))


@lru_cache(maxsize=64)
def _barycentric(n: int) -> FloatArray:
    x = _points(n)
    diff = x[:, None] - x[None, :]
    np.fill_diagonal(diff, 1.0)
    w = 1.0 / diff.prod(axis=1)
    return _read_only(w / np.max(np.abs(w)))


@lru_cache(maxsize=64)
def _differentiation(n: int) -> FloatArray:
    x = _points(n)
    w = _barycentric(n)
    diff = x[:, None] - x[None, :]
    np.fill_diagonal(diff, 1.0)
    D = (w[None, :] / w[:, None]) / diff
    np.fill_diagonal(D, 0.0)
    np.fill_diagonal(D, -D.sum(axis=1))  # rows annihilate constants exactly
    return _read_only(D)


def differentiation_matrix(n: int) -> FloatArray:
    """D with (D p)_i = p'(x_i) for every polynomial p of degree <= n sampled at the points."""
    return _differentiation(_check_degree(n))


@lru_cache(maxsize=64)
def _integration(n: int) -> FloatArray:
    # A_jl = integral from -1 to x_j of the l-th Lagrange basis polynomial: expand each basis
    # polynomial in Legendre polynomials (exact interpolation of degree n) and integrate
    x = _points(n)
    V = legendre.legvander(x, n)  # V[i, k] = P_k(x_i)
    basis = np.linalg.solve(V, np.eye(n + 1))  # column l: Legendre coefficients of l_l
    A = np.empty((n + 1, n + 1))
    for col in range(n + 1):
        antideriv = legendre.legint(basis[:, col], lbnd=-1.0)
        A[:, col] = legendre.legval(x, antideriv)
    A[0, :] = 0.0
    return _read_only(A)


def integration_matrix(n: int) -> FloatArray:
    """A with (A f)_j = integral from -1 to x_j of the degree-n interpolant of f (row 0 is zero,
    the last row is the quadrature weights)."""
    return _integration(_check_degree(n))


def interpolate(n: int, values: FloatArray, s: FloatArray) -> FloatArray:
    """The degree-n interpolant of ``values`` (n + 1 rows, at the LGL points) at ``s`` in
    [-1, 1] (second barycentric formula; exact at the points)."""
    x = _points(_check_degree(n))
    w = _barycentric(n)
    s = np.atleast_1d(np.asarray(s, dtype=float))
    diff = s[:, None] - x[None, :]
    exact = diff == 0.0
    diff[exact] = 1.0
    c = w[None, :] / diff
    out = (c @ values) / c.sum(axis=1)[(...,) + (None,) * (values.ndim - 1)]
    rows, cols = np.nonzero(exact)
    out[rows] = values[cols]
    return np.asarray(out)


@dataclass(frozen=True)
class LglMesh:
    """One phase's segments on the normalized phase time s in [0, 1]: ``breaks`` (segments + 1,
    increasing from 0 to 1) and one LGL degree for all segments. Points are numbered along the
    phase, a segment's last point being the next one's first."""

    breaks: FloatArray
    degree: int

    def __post_init__(self) -> None:
        b = np.asarray(self.breaks, dtype=float)
        if b.ndim != 1 or b.size < 2 or b[0] != 0.0 or b[-1] != 1.0 or np.any(np.diff(b) <= 0):
            raise ValueError("breaks must increase strictly from 0 to 1")
        _check_degree(self.degree)

    @classmethod
    def uniform(cls, segments: int, degree: int) -> LglMesh:
        """``segments`` equal segments of degree ``degree``."""
        if segments < 1:
            raise ValueError(f"a phase needs at least one segment, got {segments}")
        return cls(np.linspace(0.0, 1.0, segments + 1), degree)

    @property
    def segments(self) -> int:
        return int(self.breaks.size - 1)

    @property
    def points(self) -> int:
        """Number of distinct points of the phase."""
        return self.segments * self.degree + 1

    @cached_property
    def s(self) -> FloatArray:
        """Normalized time of every point, increasing, in [0, 1]."""
        x = _points(self.degree)
        b = self.breaks
        inner = (b[:-1, None] + 0.5 * (x[None, :-1] + 1.0) * np.diff(b)[:, None]).ravel()
        return _read_only(np.concatenate([inner, [1.0]]))

    @cached_property
    def quadrature(self) -> FloatArray:
        """Weights q with sum_j q_j g(s_j) = integral over [0, 1] of g (per-segment LGL)."""
        q = np.zeros(self.points)
        w = _weights(self.degree)
        for k, h in enumerate(np.diff(self.breaks)):
            q[k * self.degree : (k + 1) * self.degree + 1] += 0.5 * h * w
        return _read_only(q)

    def segment_slice(self, k: int) -> slice:
        """The points of segment ``k``."""
        return slice(k * self.degree, (k + 1) * self.degree + 1)

    def at(self, values: FloatArray, s: FloatArray) -> FloatArray:
        """The piecewise-polynomial interpolant of ``values`` (one row per point) at ``s``."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        seg = np.clip(np.searchsorted(self.breaks, s, side="right") - 1, 0, self.segments - 1)
        out = np.empty((s.size, *values.shape[1:]))
        for k in np.unique(seg):
            m = seg == k
            a, b = self.breaks[k], self.breaks[k + 1]
            local = np.clip(2.0 * (s[m] - a) / (b - a) - 1.0, -1.0, 1.0)
            out[m] = interpolate(self.degree, values[self.segment_slice(int(k))], local)
        return out
