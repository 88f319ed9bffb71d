"""Trapezoidal transcription of the energy-domain subproblem of paper 000 (sec. 3.3).

Decision vector z = [dx (K x 5, scaled deviations from the reference), u (K x 2),
soft-terminal slacks, virtual control nu (N x 5) and its bound mu (N x 5) when enabled].
Scaled deviations dx = (x - x_ref) / scale make the quadratic trust region (eq. 31) a state-scaled
one, and its slack is folded into the objective as w_tr * sum ||dx_i||^2 (at the optimum of
eq. 31 with w_tr * sum t_i, t_i equals ||dx_i||^2, so the two are the same program).

The sparsity pattern is fixed at construction; ``build`` only computes values.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from worker.solver.conic import ConeProblem, ConeSpec, SparseAssembler

Array = np.ndarray
NX = 5
NU = 2
STATE_KEYS = ("altitude_m", "longitude_deg", "latitude_deg", "flight_path_angle_deg", "heading_deg")


@dataclass(frozen=True)
class TerminalRow:
    """A terminal condition on energy-form state ``state`` (index 0..4)."""

    state: int
    kind: str  # "fixed" | "range" | "soft"
    value: float = 0.0
    lo: float = 0.0
    hi: float = 0.0
    weight: float = 0.0


@dataclass
class SubproblemData:
    """Everything that changes between SCP iterations (values, not structure)."""

    x_ref: Array  # (K, 5)
    u_ref: Array  # (K, 2)
    f: Array  # (K, 5) dx/de at the reference
    A: Array  # (K, 5, 5)
    B: Array  # (K, 5, 2)
    cost_gradient: Array  # (K, 5) d(running cost)/dx per unit energy, already weighted/scaled
    terminal_gradient: Array  # (5,) d(terminal cost)/dx_N, already weighted/scaled
    radius_lower: Array | None  # (K,) path-limit bound on r, None when no limit
    x0: Array  # (5,) initial state


@dataclass
class Unpacked:
    """A subproblem solution mapped back to states and controls."""

    x: Array
    u: Array
    soft_slacks: Array
    virtual_control: Array | None
    dx_scaled: Array


class EnergyTrapezoid:
    """Builds paper 000's Problem 2 (eq. 29-36) as a ``ConeProblem`` on a fixed pattern."""

    def __init__(
        self,
        e: Array,
        state_scale: Array,
        terminal: list[TerminalRow],
        *,
        bank_max: float,
        path_limits: bool,
        virtual_control: bool,
        weight_trust_region: float,
        weight_regularization: float,
        weight_virtual_control: float,
        weight_control_smoothness: float = 0.0,
    ) -> None:
        self.e = np.asarray(e, dtype=float)
        self.K = K = self.e.size
        self.N = N = K - 1
        self.h = np.diff(self.e)
        self.quad_w = np.zeros(K)
        self.set_grid(self.e)
        self.S = np.asarray(state_scale, dtype=float)
        self.terminal = terminal
        self.bank_cos = math.cos(bank_max)
        self.path_limits = path_limits
        self.virtual_control = virtual_control
        self.w_tr = weight_trust_region
        self.w_reg = weight_regularization
        self.w_vc = weight_virtual_control
        self.w_du = weight_control_smoothness
        self.soft = [t for t in terminal if t.kind == "soft"]

        # column layout
        self.col_x = np.arange(K * NX).reshape(K, NX)
        self.col_u = K * NX + np.arange(K * NU).reshape(K, NU)
        n = K * (NX + NU)
        self.col_soft = n + np.arange(len(self.soft))
        n += len(self.soft)
        if virtual_control:
            self.col_nu = n + np.arange(N * NX).reshape(N, NX)
            self.col_mu = n + N * NX + np.arange(N * NX).reshape(N, NX)
            n += 2 * N * NX
        self.n = n
        self._build_structure()
        self._constant_values()

    def set_grid(self, e: Array) -> None:
        """Move the nodes to energies ``e`` (same count): only values change, not the pattern."""
        e = np.asarray(e, dtype=float)
        if e.size != self.K or np.any(np.diff(e) <= 0):
            raise ValueError("a new grid must have the same number of increasing nodes")
        self.e = e
        self.h = np.diff(e)
        w = np.zeros(self.K)
        w[:-1] += 0.5 * self.h
        w[1:] += 0.5 * self.h
        self.quad_w = w  # trapezoid weights of the running cost
        self._P: sp.csc_matrix | None = None  # depends on the grid: rebuilt on the next build

    # ------------------------------------------------------------------ structure
    def _build_structure(self) -> None:
        K, N = self.K, self.N
        rows: list[Array] = []
        cols: list[Array] = []
        row = 0
        # dynamics rows 5*i + j: X(i,k), X(i+1,k), U(i,m), U(i+1,m) [, nu(i,j)]
        i = np.arange(N)[:, None, None]
        j = np.arange(NX)[None, :, None]
        dyn_row = (NX * i + j) + np.zeros((1, 1, NX), dtype=int)
        rows.append(dyn_row.ravel())
        cols.append(np.broadcast_to(self.col_x[:-1][:, None, :], (N, NX, NX)).ravel())
        rows.append(dyn_row.ravel())
        cols.append(np.broadcast_to(self.col_x[1:][:, None, :], (N, NX, NX)).ravel())
        dyn_row_u = (NX * i + j) + np.zeros((1, 1, NU), dtype=int)
        rows.append(dyn_row_u.ravel())
        cols.append(np.broadcast_to(self.col_u[:-1][:, None, :], (N, NX, NU)).ravel())
        rows.append(dyn_row_u.ravel())
        cols.append(np.broadcast_to(self.col_u[1:][:, None, :], (N, NX, NU)).ravel())
        if self.virtual_control:
            rows.append(np.arange(N * NX))
            cols.append(self.col_nu.ravel())
        row = N * NX
        # initial state rows
        rows.append(row + np.arange(NX))
        cols.append(self.col_x[0])
        row += NX
        fixed = [t for t in self.terminal if t.kind == "fixed"]
        for t in fixed:
            rows.append(np.array([row]))
            cols.append(np.array([self.col_x[-1, t.state]]))
            row += 1
        self.n_zero = row
        # nonnegative rows
        if self.path_limits:
            self.row_path = row
            rows.append(row + np.arange(K))
            cols.append(self.col_x[:, 0])
            row += K
        self.row_bank = row
        rows.append(row + np.arange(K))
        cols.append(self.col_u[:, 0])
        row += K
        for s, t in enumerate(self.soft):
            for _sign in (1.0, -1.0):
                rows.append(np.array([row, row]))
                cols.append(np.array([self.col_x[-1, t.state], self.col_soft[s]]))
                row += 1
        for t in self.terminal:
            if t.kind == "range":
                rows.append(np.array([row, row + 1]))
                cols.append(np.array([self.col_x[-1, t.state]] * 2))
                row += 2
        if self.virtual_control:
            for _sign in (1.0, -1.0):
                rows.append(row + np.arange(N * NX))
                cols.append(self.col_nu.ravel())
                rows.append(row + np.arange(N * NX))
                cols.append(self.col_mu.ravel())
                row += N * NX
        self.n_nonneg = row - self.n_zero
        # SOC blocks (1, u1, u2) >= 0 in the cone: |u| <= 1 (eq. 35)
        self.row_soc = row
        soc_rows = row + 3 * np.arange(K)[:, None] + np.array([1, 2])[None, :]
        rows.append(soc_rows.ravel())
        cols.append(self.col_u.ravel())
        row += 3 * K
        self.m = row
        self.cones = ConeSpec(self.n_zero, self.n_nonneg, tuple([3] * K))
        self.A_asm = SparseAssembler(np.concatenate(rows), np.concatenate(cols), (self.m, self.n))
        # P: trust region on the scaled state deviations (diagonal), control smoothness on u
        # (tridiagonal in nodes: w * sum_i c_i |u_{i+1} - u_i|^2)
        diag = self.col_x.ravel()
        cu = self.col_u
        p_rows = [diag, cu.ravel(), cu[:-1].ravel()]
        p_cols = [diag, cu.ravel(), cu[1:].ravel()]
        self.P_asm = SparseAssembler(
            np.concatenate(p_rows), np.concatenate(p_cols), (self.n, self.n), upper_triangular=True
        )

    # ------------------------------------------------------------------ values
    def _constant_values(self) -> None:
        """Fill the triplet values, b and q entries that do not depend on the reference.

        ``build`` then writes only the reference-dependent entries into copies of these.
        """
        K, N, S = self.K, self.N, self.S
        vals: list[Array] = []
        n_dyn = 2 * N * NX * NX + 2 * N * NX * NU
        vals.append(np.zeros(n_dyn))  # dynamics blocks, written by build
        if self.virtual_control:
            vals.append(-np.ones(N * NX))
        b: list[Array] = [np.zeros(N * NX)]  # dynamics residuals, written by build
        vals.append(np.ones(NX))
        b.append(np.zeros(NX))  # initial state, written by build
        for t in self.terminal:
            if t.kind == "fixed":
                vals.append(np.ones(1))
                b.append(np.zeros(1))
        if self.path_limits:
            vals.append(np.full(K, -S[0]))
            b.append(np.zeros(K))
        vals.append(-np.ones(K))
        b.append(np.full(K, -self.bank_cos))
        for t in self.soft:
            vals.append(np.array([S[t.state], -1.0]))
            b.append(np.zeros(1))
            vals.append(np.array([-S[t.state], -1.0]))
            b.append(np.zeros(1))
        for t in self.terminal:
            if t.kind == "range":
                vals.append(np.array([S[t.state], -S[t.state]]))
                b.append(np.zeros(2))
        if self.virtual_control:
            for sign in (1.0, -1.0):
                vals.append(np.full(N * NX, sign))
                vals.append(-np.ones(N * NX))
                b.append(np.zeros(N * NX))
        vals.append(-np.ones(K * NU))
        soc_b = np.zeros((K, 3))
        soc_b[:, 0] = 1.0
        b.append(soc_b.ravel())
        self._vals = np.concatenate(vals)
        # Without duplicate triplets each triplet owns one CSC data slot: the constant entries
        # are placed once and build writes the dynamics blocks straight into their slots.
        self._direct = not self.A_asm.has_duplicates
        if self._direct:
            self._A_data = self.A_asm.assemble_data(self._vals)
            pos = self.A_asm.positions
            sizes = (N * NX * NX, N * NX * NX, N * NX * NU, N * NX * NU)
            bounds = np.cumsum((0, *sizes))
            self._block_slots = [pos[a:b] for a, b in itertools.pairwise(bounds)]
        self._b = np.concatenate(b)
        self._n_dyn = n_dyn
        q = np.zeros(self.n)
        for s, t in enumerate(self.soft):
            q[self.col_soft[s]] = t.weight
        if self.virtual_control:
            q[self.col_mu] = self.w_vc
        self._q = q
        self._eye_s = np.eye(NX)[None, :, :] * S[None, :, None]
        self._neg_eye_s = -self._eye_s

    def _objective_matrix(self) -> sp.csc_matrix:
        """P on the current grid (trust region and control smoothness); cached until regrid."""
        if self._P is None:
            K, h = self.K, self.h
            c = self.w_du * np.mean(h) / h  # per-interval weight: a penalty on the rate du/de
            u_diag = np.zeros(K)
            u_diag[:-1] += 2.0 * c
            u_diag[1:] += 2.0 * c
            self._P = self.P_asm.assemble(
                np.concatenate(
                    [
                        np.full(K * NX, 2.0 * self.w_tr),
                        np.repeat(u_diag, NU),
                        np.repeat(-2.0 * c, NU),
                    ]
                )
            )
        return self._P

    def build(self, d: SubproblemData) -> ConeProblem:
        """Assemble the subproblem linearized about ``d.x_ref``, ``d.u_ref``.

        The returned P is shared by every problem built on the same grid (treat it as read-only).
        """
        K, N, S, h = self.K, self.N, self.S, self.h
        half = 0.5 * h[:, None, None]
        S_row = S[None, None, :]
        # dA_i[j,k] = -delta_jk S_j - h/2 A_i[j,k] S_k ;  dA_{i+1} = +delta S - h/2 A_{i+1} S
        blocks = (
            self._neg_eye_s - half * d.A[:-1] * S_row,
            self._eye_s - half * d.A[1:] * S_row,
            -half * d.B[:-1],
            -half * d.B[1:],
        )
        if self._direct:
            data = self._A_data.copy()
            for slots, block in zip(self._block_slots, blocks, strict=True):
                data[slots] = block.ravel()
            A = self.A_asm.matrix(data)
        else:
            vals = self._vals.copy()
            pos = 0
            for block in blocks:
                vals[pos : pos + block.size] = block.ravel()
                pos += block.size
            A = self.A_asm.assemble(vals)
        b = self._b.copy()
        c = d.f - np.einsum("kjm,km->kj", d.B, d.u_ref)
        b_dyn = -(d.x_ref[1:] - d.x_ref[:-1]) + 0.5 * h[:, None] * (c[:-1] + c[1:])
        row = N * NX
        b[:row] = b_dyn.ravel()
        b[row : row + NX] = (d.x0 - d.x_ref[0]) / S
        row += NX
        for t in self.terminal:
            if t.kind == "fixed":
                b[row] = (t.value - d.x_ref[-1, t.state]) / S[t.state]
                row += 1
        if self.path_limits:
            assert d.radius_lower is not None
            b[row : row + K] = d.x_ref[:, 0] - d.radius_lower
            row += K
        row += K  # bank rows: constant
        for t in self.soft:
            off = t.value - d.x_ref[-1, t.state]
            b[row] = off
            b[row + 1] = -off
            row += 2
        for t in self.terminal:
            if t.kind == "range":
                xr = d.x_ref[-1, t.state]
                b[row] = t.hi - xr
                b[row + 1] = -(t.lo - xr)
                row += 2

        q = self._q.copy()
        q_x = q[: K * NX].reshape(K, NX)  # the state columns come first (view)
        q_x[:] = (d.cost_gradient * self.quad_w[:, None]) * S[None, :]
        q_x[-1] += d.terminal_gradient * S
        # regularization: reward the component of u along the reference bank direction, the
        # linearization of |u| at u_ref, which drives |u| to 1 (exact relaxation, eq. 22)
        norm = np.linalg.norm(d.u_ref, axis=1)
        direction = np.where(
            norm[:, None] > 1e-9, d.u_ref / np.maximum(norm, 1e-9)[:, None], np.array([1.0, 0.0])
        )
        q[self.col_u] = -self.w_reg * self.quad_w[:, None] * direction
        return ConeProblem(P=self._objective_matrix(), q=q, A=A, b=b, cones=self.cones)

    def unpack(self, z: Array, d: SubproblemData) -> Unpacked:
        """States, controls and slacks of a subproblem solution ``z``."""
        dx = z[self.col_x]
        x = d.x_ref + dx * self.S[None, :]
        u = z[self.col_u]
        nu = z[self.col_nu] if self.virtual_control else None
        return Unpacked(x=x, u=u, soft_slacks=z[self.col_soft], virtual_control=nu, dx_scaled=dx)
