"""Trapezoidal transcription of the energy-domain subproblem of paper 000 (sec. 3.3).

Decision vector z = [dx (K x nx, scaled deviations from the reference), u (K x 2),
soft-terminal slacks, virtual control nu (N x nx) and its bound mu (N x nx) when enabled].
Scaled deviations dx = (x - x_ref) / scale make the quadratic trust region (eq. 31) a state-scaled
one, and its slack is folded into the objective as w_tr * sum ||dx_i||^2 (at the optimum of
eq. 31 with w_tr * sum t_i, t_i equals ||dx_i||^2, so the two are the same program).

The rows are declared once as blocks (``transcription.rows``); the sparsity pattern is fixed at
construction and ``build`` only computes values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from worker.solver.conic import ConeProblem, SparseAssembler
from worker.solver.models.layout import ENERGY, StateLayout
from worker.solver.transcription.energy_rows import row_blocks
from worker.solver.transcription.rows import Columns, RowSystem
from worker.solver.transcription.terminal import TerminalRow

Array = np.ndarray
NU = 2
"""Controls of the relaxation: u = (cos sigma, sin sigma) with |u| <= 1 (paper 000 eq. 22)."""


@dataclass
class SubproblemData:
    """Everything that changes between SCP iterations (values, not structure)."""

    x_ref: Array  # (K, nx)
    u_ref: Array  # (K, 2)
    f: Array  # (K, nx) dx/de at the reference
    A: Array  # (K, nx, nx)
    B: Array  # (K, nx, 2)
    cost_gradient: Array  # (K, nx) d(running cost)/dx per unit energy, already weighted/scaled
    terminal_gradient: Array  # (nx,) d(terminal cost)/dx_N, already weighted/scaled
    radius_lower: Array | None  # (K,) path-limit bound on r, None when no limit
    x0: Array  # (nx,) initial state
    bank_step_max: Array | None = None  # (N,) bound on |sigma_{i+1} - sigma_i| (bank-rate rows)
    defect: Array | None = None  # (N, nx) the trapezoid's error at the reference (energy_defect)


@dataclass
class Unpacked:
    """A subproblem solution mapped back to states and controls."""

    x: Array
    u: Array
    soft_slacks: Array
    virtual_control: Array | None
    dx_scaled: Array


class EnergyTrapezoid:
    """Builds paper 000's Problem 2 (eq. 29-36) as a ``ConeProblem`` on a fixed pattern.

    ``layout`` names the states (``state_scale`` holds one scale per state); the radius comes
    first, as the path-limit rows expect.
    """

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
        weight_regularization: float | Array,
        weight_virtual_control: float,
        weight_control_smoothness: float = 0.0,
        bank_rate_rows: bool = False,
        layout: StateLayout = ENERGY,
    ) -> None:
        self.e = np.asarray(e, dtype=float)
        self.K = K = self.e.size
        self.N = N = K - 1
        self.h = np.diff(self.e)
        self.quad_w = np.zeros(K)
        self.set_grid(self.e)
        self.layout = layout
        self.nx = nx = layout.size
        self.S = np.asarray(state_scale, dtype=float)
        if self.S.shape != (nx,):
            raise ValueError(f"state_scale needs {nx} entries for the {layout.name} layout")
        self.terminal = terminal
        self.bank_cos = math.cos(bank_max)
        self.path_limits = path_limits
        self.virtual_control = virtual_control
        self.w_tr = weight_trust_region
        self.w_reg = np.broadcast_to(np.asarray(weight_regularization, dtype=float), (K,)).copy()
        self.w_vc = weight_virtual_control
        self.w_du = weight_control_smoothness
        self.bank_rate_rows = bank_rate_rows
        self.soft = [t for t in terminal if t.kind == "soft"]

        self.columns = cols = Columns()
        self.col_x = cols.add("x", K, nx)
        self.col_u = cols.add("u", K, NU)
        self.col_soft = cols.add("soft", len(self.soft))
        if virtual_control:
            self.col_nu = cols.add("nu", N, nx)
            self.col_mu = cols.add("mu", N, nx)
        self.n = cols.n
        self.rows = RowSystem(row_blocks(self), self.n)
        self.A_asm = self.rows.assembler
        self.cones = self.rows.cones
        self.m = self.rows.m
        self.n_zero = self.cones.n_zero
        self.n_nonneg = self.cones.n_nonneg
        self.row_soc = self.rows.start("control_norm")
        # P: trust region on the scaled state deviations (diagonal), control smoothness on the
        # step of u (tridiagonal in nodes: w sum_i c_i |(u_{i+1} - u_i) - (ub_{i+1} - ub_i)|^2)
        diag = self.col_x.ravel()
        cu = self.col_u
        p_rows = [diag, cu.ravel(), cu[:-1].ravel()]
        p_cols = [diag, cu.ravel(), cu[1:].ravel()]
        self.P_asm = SparseAssembler(
            np.concatenate(p_rows), np.concatenate(p_cols), (self.n, self.n), upper_triangular=True
        )
        self._q_constant: dict[str, Array | float] = {
            "soft": np.array([t.weight for t in self.soft], dtype=float)
        }
        if virtual_control:
            self._q_constant["mu"] = self.w_vc

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

    def set_weights(self, trust_region: float, regularization: Array) -> None:
        """New trust-region weight and per-node regularization weights (K,) for the next
        build: values only, the pattern stays."""
        if trust_region != self.w_tr:
            self.w_tr = trust_region
            self._P = None
        self.w_reg = np.asarray(regularization, dtype=float).copy()

    def _smoothness_weights(self) -> Array:
        """Per-interval weight c_i of the control-smoothness term: a penalty on the rate du/de."""
        return self.w_du * np.mean(self.h) / self.h

    def _objective_matrix(self) -> sp.csc_matrix:
        """P on the current grid (trust region and control smoothness); cached until regrid."""
        if self._P is None:
            K = self.K
            c = self._smoothness_weights()
            u_diag = np.zeros(K)
            u_diag[:-1] += 2.0 * c
            u_diag[1:] += 2.0 * c
            self._P = self.P_asm.assemble(
                np.concatenate(
                    [
                        np.full(K * self.nx, 2.0 * self.w_tr),
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
        S = self.S
        A = self.rows.A(d)
        b = self.rows.b(d)
        q_x = (d.cost_gradient * self.quad_w[:, None]) * S[None, :]
        q_x[-1] += d.terminal_gradient * S
        # regularization: reward the component of u along the reference bank direction, the
        # linearization of |u| at u_ref, which drives |u| to 1 (exact relaxation, eq. 22)
        norm = np.linalg.norm(d.u_ref, axis=1)
        direction = np.where(
            norm[:, None] > 1e-9, d.u_ref / np.maximum(norm, 1e-9)[:, None], np.array([1.0, 0.0])
        )
        q_u = -(self.w_reg * self.quad_w)[:, None] * direction
        # smoothness acts on the step of the control differences, so it vanishes (value and
        # gradient) at convergence and does not bias the optimum: the linear part of
        # c_i |D u - D ubar|^2 is -2 c_i D ubar . D u
        if self.w_du > 0:
            du_ref = 2.0 * self._smoothness_weights()[:, None] * np.diff(d.u_ref, axis=0)
            q_u[:-1] += du_ref
            q_u[1:] -= du_ref
        q = self.columns.vector({**self._q_constant, "x": q_x, "u": q_u})
        return ConeProblem(P=self._objective_matrix(), q=q, A=A, b=b, cones=self.cones)

    def unpack(self, z: Array, d: SubproblemData) -> Unpacked:
        """States, controls and slacks of a subproblem solution ``z``."""
        dx = z[self.col_x]
        x = d.x_ref + dx * self.S[None, :]
        u = z[self.col_u]
        nu = z[self.col_nu] if self.virtual_control else None
        return Unpacked(x=x, u=u, soft_slacks=z[self.col_soft], virtual_control=nu, dx_scaled=dx)
