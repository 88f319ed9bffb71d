"""Trapezoidal transcription of the energy-domain subproblem of paper 000 (sec. 3.3).

Decision vector z = [dx (K x 5, scaled deviations from the reference), u (K x 2),
soft-terminal slacks, virtual control nu (N x 5) and its bound mu (N x 5) when enabled].
Scaled deviations dx = (x - x_ref) / scale make the quadratic trust region (eq. 31) a state-scaled
one, and its slack is folded into the objective as w_tr * sum ||dx_i||^2 (at the optimum of
eq. 31 with w_tr * sum t_i, t_i equals ||dx_i||^2, so the two are the same program).

The sparsity pattern is fixed at construction; ``build`` only computes values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

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
    def build(self, d: SubproblemData) -> ConeProblem:
        """Assemble the subproblem linearized about ``d.x_ref``, ``d.u_ref``."""
        K, N, S, h = self.K, self.N, self.S, self.h
        vals: list[Array] = []
        half = 0.5 * h[:, None, None]
        eye = np.eye(NX)[None, :, :] * S[None, :, None]
        # dA_i[j,k] = -delta_jk S_j - h/2 A_i[j,k] S_k ;  dA_{i+1} = +delta S - h/2 A_{i+1} S
        vals.append((-eye - half * d.A[:-1] * S[None, None, :]).ravel())
        vals.append((eye - half * d.A[1:] * S[None, None, :]).ravel())
        vals.append((-half * d.B[:-1]).ravel())
        vals.append((-half * d.B[1:]).ravel())
        if self.virtual_control:
            vals.append(-np.ones(N * NX))
        c = d.f - np.einsum("kjm,km->kj", d.B, d.u_ref)
        b_dyn = -(d.x_ref[1:] - d.x_ref[:-1]) + 0.5 * h[:, None] * (c[:-1] + c[1:])
        b: list[Array] = [b_dyn.ravel()]
        vals.append(np.ones(NX))
        b.append((d.x0 - d.x_ref[0]) / S)
        for t in self.terminal:
            if t.kind == "fixed":
                vals.append(np.ones(1))
                b.append(np.array([(t.value - d.x_ref[-1, t.state]) / S[t.state]]))
        if self.path_limits:
            assert d.radius_lower is not None
            vals.append(np.full(K, -S[0]))
            b.append(d.x_ref[:, 0] - d.radius_lower)
        vals.append(-np.ones(K))
        b.append(np.full(K, -self.bank_cos))
        for t in self.soft:
            off = t.value - d.x_ref[-1, t.state]
            vals.append(np.array([S[t.state], -1.0]))
            b.append(np.array([off]))
            vals.append(np.array([-S[t.state], -1.0]))
            b.append(np.array([-off]))
        for t in self.terminal:
            if t.kind == "range":
                xr = d.x_ref[-1, t.state]
                vals.append(np.array([S[t.state], -S[t.state]]))
                b.append(np.array([t.hi - xr, -(t.lo - xr)]))
        if self.virtual_control:
            for sign in (1.0, -1.0):
                vals.append(np.full(N * NX, sign))
                vals.append(-np.ones(N * NX))
                b.append(np.zeros(N * NX))
        vals.append(-np.ones(K * NU))
        soc_b = np.zeros((K, 3))
        soc_b[:, 0] = 1.0
        b.append(soc_b.ravel())
        A = self.A_asm.assemble(np.concatenate(vals))

        q = np.zeros(self.n)
        q[self.col_x] = (d.cost_gradient * self.quad_w[:, None]) * S[None, :]
        q[self.col_x[-1]] += d.terminal_gradient * S
        # regularization: reward the component of u along the reference bank direction, the
        # linearization of |u| at u_ref, which drives |u| to 1 (exact relaxation, eq. 22)
        norm = np.linalg.norm(d.u_ref, axis=1)
        direction = np.where(
            norm[:, None] > 1e-9, d.u_ref / np.maximum(norm, 1e-9)[:, None], np.array([1.0, 0.0])
        )
        q[self.col_u] = -self.w_reg * self.quad_w[:, None] * direction
        for s, t in enumerate(self.soft):
            q[self.col_soft[s]] = t.weight
        if self.virtual_control:
            q[self.col_mu] = self.w_vc
        c = self.w_du * np.mean(h) / h  # per-interval weight: a penalty on the rate du/de
        u_diag = np.zeros(K)
        u_diag[:-1] += 2.0 * c
        u_diag[1:] += 2.0 * c
        P = self.P_asm.assemble(
            np.concatenate(
                [
                    np.full(K * NX, 2.0 * self.w_tr),
                    np.repeat(u_diag, NU),
                    np.repeat(-2.0 * c, NU),
                ]
            )
        )
        return ConeProblem(P=P, q=q, A=A, b=np.concatenate(b), cones=self.cones)

    def unpack(self, z: Array, d: SubproblemData) -> Unpacked:
        """States, controls and slacks of a subproblem solution ``z``."""
        dx = z[self.col_x]
        x = d.x_ref + dx * self.S[None, :]
        u = z[self.col_u]
        nu = z[self.col_nu] if self.virtual_control else None
        return Unpacked(x=x, u=u, soft_slacks=z[self.col_soft], virtual_control=nu, dx_scaled=dx)
