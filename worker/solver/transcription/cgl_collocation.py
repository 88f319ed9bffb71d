"""Multi-interval CGL collocation in integral form, with free final time: the defect rows of a
``ChebyshevMesh`` and their linearization.

On interval k (fraction h_k of the normalized span [0, 1], degree n_k, global points p..p+n_k)
the states at the interval's points satisfy, for i = 1..n_k,

    z_{p+i} - z_p = (h_k / 2) sum_j B_ij F(z_{p+j}, w_{p+j}, t_f),    F = t_f f(z, w),

B the CGL integration matrix (``cgl.integration_matrix``): the integral (Birkhoff) form of the
pseudospectral collocation, which gives n_k rows per interval for its n_k new points, so the
shared boundary points carry the continuity and no point is collocated twice (paper 003 sec. 3.1
uses the differential form D z = (h_k t_f / 2) f; both are exact for polynomial states of degree
n_k). Final time free: t = t_f tau with tau in [0, 1] (paper 003 eq. 51 linearized through S =
dF/dt_f = f).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from worker.solver.transcription.cgl import (
    ChebyshevMesh,
    cgl_points,
    integration_matrix,
    interpolate,
)

Array = np.ndarray
SAMPLES_PER_GAP = 3
"""Samples between consecutive points of the interpolated states for the path limits
(``PolynomialSamples.between``): on paper 003's case 3 leave the propagated load factor within
0.3 % of its limit."""


@dataclass(frozen=True)
class CollocationPattern:
    """Index arrays of the defect rows of a mesh for ``nz`` states and ``nw`` controls.

    Row (m, a): the m-th collocated point (global points 1..K-1 in order, one per row block)
    and state a. ``rows_z``/``cols_z`` give the entries on the state changes (point, state)
    and ``rows_w``/``cols_w`` those on the control changes; each entry's interval coefficient
    is ``coef`` (h_k / 2 B_ij) at (row point, column point) ``pair_row``, ``pair_col``.
    """

    mesh: ChebyshevMesh
    nz: int
    nw: int
    pair_row: Array  # (P,) global point index of the collocated point i
    pair_col: Array  # (P,) global point index of the point j it integrates
    coef: Array  # (P,) (h_k / 2) B_ij
    start: Array  # (K-1,) global index of the interval's first point, per collocated point

    @classmethod
    def of(cls, mesh: ChebyshevMesh, nz: int, nw: int) -> CollocationPattern:
        """The pattern of ``mesh``."""
        rows, cols, coef, start = [], [], [], []
        h = np.diff(np.asarray(mesh.boundaries))
        for hk, n, sl in zip(h, mesh.degrees, mesh.interval_slices(), strict=True):
            B = integration_matrix(n)
            p = sl.start
            for i in range(1, n + 1):
                for j in range(n + 1):
                    rows.append(p + i)
                    cols.append(p + j)
                    coef.append(0.5 * hk * B[i, j])
                start.append(p)
        return cls(
            mesh,
            nz,
            nw,
            np.asarray(rows, dtype=np.int64),
            np.asarray(cols, dtype=np.int64),
            np.asarray(coef, dtype=float),
            np.asarray(start, dtype=np.int64),
        )

    @property
    def num_points(self) -> int:
        """Points of the mesh (K)."""
        return self.mesh.num_points

    @cached_property
    def samples(self) -> PolynomialSamples:
        """Each interval's polynomial sampled at its points and between them (see
        :class:`PolynomialSamples`)."""
        return PolynomialSamples.of(self.mesh, SAMPLES_PER_GAP, elevated=True)

    def defects(self, z: Array, F: Array) -> Array:
        """(K-1, nz) residuals z_{p+i} - z_p - sum_j (h_k/2) B_ij F_{p+j} of each collocated
        point (zero on an exact solution of the collocation equations)."""
        integral = np.zeros((self.num_points, self.nz), dtype=np.result_type(z, F))
        np.add.at(integral, self.pair_row, self.coef[:, None] * F[self.pair_col])
        return z[1:] - z[self.start] - integral[1:]


def _between(tau: Array, per_gap: int) -> Array:
    """``per_gap`` equally spaced points inside each gap of the increasing ``tau``."""
    share = np.arange(1, per_gap + 1) / (per_gap + 1)
    return (tau[:-1, None] + share[None, :] * np.diff(tau)[:, None]).ravel()


def bernstein_from_cgl(n: int) -> Array:
    """(n+1, n+1) map from a degree-n polynomial's values at the CGL points to its Bernstein
    coefficients on [-1, 1]: the polynomial lies within the range of its coefficients, and its
    first and last coefficients are its end values (Farouki (2012), Comput. Aided Geom. Des. 29,
    sec. 2)."""
    x = 0.5 * (cgl_points(n) + 1.0)
    j = np.arange(n + 1)
    binom = np.array([math.comb(n, k) for k in j], dtype=float)
    basis = binom[None, :] * x[:, None] ** j[None, :] * (1.0 - x[:, None]) ** (n - j)[None, :]
    return np.linalg.solve(basis, np.eye(n + 1))


def degree_elevation(n: int, m: int) -> Array:
    """(n+m+1, n+1) map from the Bernstein coefficients of a degree-n polynomial to those of the
    same polynomial written at degree n+m; their range narrows towards the polynomial's as m
    grows (Farouki (2012), sec. 5)."""
    out = np.zeros((n + m + 1, n + 1))
    for i in range(n + m + 1):
        for j in range(max(0, i - m), min(n, i) + 1):
            out[i, j] = math.comb(n, j) * math.comb(m, i - j) / math.comb(n + m, i)
    return out


@dataclass(frozen=True)
class PolynomialSamples:
    """Linear maps from the point values x of a mesh's piecewise polynomial to what bounds on it
    between the points need; each row acts on ``*_idx`` (one interval's points, padded to the
    largest degree with zero coefficients on a repeated index).

    - ``between``: its values at ``per_gap`` equally spaced times in each gap between points
      (for limits on functions of the states, which are only sampled);
    - ``hull``: its interior Bernstein coefficients: between bounds at the points and on these,
      the polynomial is within them everywhere on its interval;
    - ``slope``: the Bernstein coefficients of its derivative with respect to the normalized time
      t / t_f ((n / h_k) times the differences of its coefficients): divided by t_f they bound the
      rate a flight of the polynomial sees, so |slope @ x| <= r t_f, linear in the point values
      and t_f together, holds the rate within r everywhere (the collocated rates at the points are
      not the polynomial's derivative).
    """

    between_idx: Array
    between: Array
    between_owner: Array
    """The point nearest each ``between`` sample (the largest of its Lagrange coefficients)."""
    hull_idx: Array
    hull: Array
    slope_idx: Array
    slope: Array

    @classmethod
    def of(cls, mesh: ChebyshevMesh, per_gap: int = 1, elevated: bool = False) -> PolynomialSamples:
        """The maps of ``mesh``; ``elevated``: the hulls of each interval's polynomials written
        at twice their degree (measured on paper 003's case: t_f 1332.58 s in 40 iterations,
        against 1333.61 s in 44 with the plain hulls; three times the degree gave the same
        1332.57 s in 54)."""
        width = max(mesh.degrees) + 1
        h = np.diff(np.asarray(mesh.boundaries))
        parts: dict[str, list[Array]] = {k: [] for k in ("bi", "b", "hi", "h", "si", "s")}
        for hk, n, sl in zip(h, mesh.degrees, mesh.interval_slices(), strict=True):
            tau = cgl_points(n)
            idx = np.arange(sl.start, sl.stop)
            pad = width - (n + 1)
            padded = np.concatenate([idx, np.full(pad, idx[-1])])
            at = interpolate(np.eye(n + 1), n, _between(tau, per_gap))
            coefficients = bernstein_from_cgl(n)
            slope = (n / hk) * np.diff(coefficients, axis=0)  # (n, n+1)
            if elevated:
                coefficients = degree_elevation(n, n) @ coefficients
                slope = degree_elevation(n - 1, n) @ slope
            for key, rows in (("b", at), ("h", coefficients[1:-1]), ("s", slope)):
                parts[key + "i"].append(np.tile(padded, (rows.shape[0], 1)))
                parts[key].append(np.pad(rows, ((0, 0), (0, pad))))
        out = {k: np.concatenate(v) for k, v in parts.items()}
        between_idx = out["bi"].astype(np.int64)
        owner = between_idx[np.arange(between_idx.shape[0]), np.argmax(out["b"], axis=1)]
        return cls(
            between_idx,
            out["b"],
            owner,
            out["hi"].astype(np.int64),
            out["h"],
            out["si"].astype(np.int64),
            out["s"],
        )


@dataclass(frozen=True)
class PolynomialAttitude:
    """Bank (rad) and angle of attack (rad) as the mesh's piecewise polynomials through their
    values at the points, over [0, t_f] (nondimensional): ``trajectory.AttitudePath``. The rates
    are the polynomials' exact derivatives (``differentiation_matrices`` at the points,
    interpolated at the same degree)."""

    mesh: ChebyshevMesh
    tf: float
    bank: Array  # (K,)
    alpha: Array  # (K,) radians

    def _values(self) -> Array:
        return np.column_stack([self.bank, self.alpha])

    def at(self, t: Array) -> tuple[Array, Array]:
        """(bank rad, alpha deg) at nondimensional times ``t`` (clipped to [0, t_f])."""
        tt = np.clip(np.asarray(t, dtype=float), 0.0, self.tf)
        v = self.mesh.interpolate(self._values(), 0.0, self.tf, tt)
        return v[..., 0], np.degrees(v[..., 1])

    def rates_at(self, t: Array) -> tuple[Array, Array]:
        """(d bank/dt, d alpha/dt) in rad per nondimensional time at times ``t``: on each
        interval the exact derivative of its own polynomial (at a shared point the earlier
        interval's, which the later one's meets only at convergence of the mesh)."""
        tt = np.clip(np.asarray(t, dtype=float), 0.0, self.tf)
        flat = tt.reshape(-1)
        edges = self.mesh.interval_times(0.0, self.tf)
        which = np.clip(np.searchsorted(edges[1:-1], flat, side="left"), 0, len(edges) - 2)
        values = self._values()
        out = np.empty((flat.size, 2))
        derivatives = self.mesh.differentiation_matrices(0.0, self.tf)
        for k, (n, sl) in enumerate(
            zip(self.mesh.degrees, self.mesh.interval_slices(), strict=True)
        ):
            mask = which == k
            if not np.any(mask):
                continue
            a, b = edges[k], edges[k + 1]
            tau = np.clip((2.0 * flat[mask] - a - b) / (b - a), -1.0, 1.0)
            out[mask] = interpolate(derivatives[k] @ values[sl], n, tau)
        return out[:, 0].reshape(tt.shape), out[:, 1].reshape(tt.shape)
