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

from dataclasses import dataclass

import numpy as np

from worker.solver.transcription.cgl import ChebyshevMesh, integration_matrix, interpolate

Array = np.ndarray


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

    def defects(self, z: Array, F: Array) -> Array:
        """(K-1, nz) residuals z_{p+i} - z_p - sum_j (h_k/2) B_ij F_{p+j} of each collocated
        point (zero on an exact solution of the collocation equations)."""
        integral = np.zeros((self.num_points, self.nz), dtype=np.result_type(z, F))
        np.add.at(integral, self.pair_row, self.coef[:, None] * F[self.pair_col])
        return z[1:] - z[self.start] - integral[1:]


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
