"""The row blocks of the energy-domain subproblem (paper 000 Problem 2, eq. 29-36), each
declared once.

Equalities: the trapezoidal dynamics on the scaled deviations (eq. 30, plus the virtual control
nu when enabled), the initial state and the fixed terminal states. Nonnegative rows: the radius
above its path-limit bound (eq. 33), u1 >= cos sigma_max (eq. 34), the soft and range terminal
rows, |nu| <= mu and, when enabled, the bank step between nodes bounded on the bank angle
linearized at the reference (against node-to-node chatter). Second-order cones: |u| <= 1 at
every node (eq. 35).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from worker.solver.transcription.rows import RowBlock, Term
from worker.solver.transcription.terminal import range_block, soft_block

if TYPE_CHECKING:
    from worker.solver.transcription.energy_trapezoid import EnergyTrapezoid, SubproblemData

Array = np.ndarray
BANK_DIRECTION_MIN = 0.1
"""Below this |u| the reference has no bank direction to linearize the bank angle about."""


def _radius_lower(d: SubproblemData) -> Array:
    """The path-limit bound on the radius (present whenever the pattern has path rows)."""
    assert d.radius_lower is not None
    return d.radius_lower


def _bank_tangents(d: SubproblemData) -> Array:
    """(K, 2) gradients of the bank angle atan2(u2, u1) at the reference controls, zero where
    the reference has no bank direction (|u| small): sigma ~ sigma_ref + t . u."""
    norm2 = np.sum(d.u_ref**2, axis=1)
    t = np.column_stack([-d.u_ref[:, 1], d.u_ref[:, 0]]) / np.maximum(norm2, 1e-12)[:, None]
    return np.where(norm2[:, None] > BANK_DIRECTION_MIN**2, t, 0.0)


def _bank_step_rhs(d: SubproblemData) -> Array:
    """Right-hand sides of the linearized bank-rate rows: cap -/+ the reference's bank step."""
    assert d.bank_step_max is not None
    ref = np.arctan2(d.u_ref[:, 1], d.u_ref[:, 0])
    step = np.angle(np.exp(1j * np.diff(ref)))  # wrapped to (-pi, pi]
    norm = np.linalg.norm(d.u_ref, axis=1)
    live = (norm[1:] > BANK_DIRECTION_MIN) & (norm[:-1] > BANK_DIRECTION_MIN)
    cap = np.where(live, np.maximum(d.bank_step_max, np.abs(step)), 1e3)
    return np.concatenate([cap - step, cap + step])


def _last_node(d: SubproblemData) -> Array:
    """The reference's last node."""
    return d.x_ref[-1]


def dynamics_block(tr: EnergyTrapezoid) -> RowBlock[SubproblemData]:
    """Rows nx i + j: S_j dx_{i+1,j} - S_j dx_{i,j} - h_i/2 (A_i S dx_i + A_{i+1} S dx_{i+1}
    + B_i u_i + B_{i+1} u_{i+1}) [- nu_i,j] = the trapezoid's defect of the reference (plus its
    discretization error there when the deferred correction is on); the step h follows the
    current grid."""
    N, nx = tr.N, tr.nx
    S = tr.S
    eye_s = np.eye(nx)[None, :, :] * S[None, :, None]
    neg_eye_s = -eye_s
    row = (nx * np.arange(N)[:, None] + np.arange(nx)[None, :])[:, :, None]

    def half() -> Array:
        """h_i / 2 on the current grid, shaped for the (N, nx, .) blocks."""
        return 0.5 * tr.h[:, None, None]

    # dA_i[j,k] = -delta_jk S_j - h/2 A_i[j,k] S_k ;  dA_{i+1} = +delta S - h/2 A_{i+1} S
    terms: list[Term[SubproblemData]] = [
        Term(row, tr.col_x[:-1][:, None, :], update=lambda d: neg_eye_s - half() * d.A[:-1] * S),
        Term(row, tr.col_x[1:][:, None, :], update=lambda d: eye_s - half() * d.A[1:] * S),
        Term(row, tr.col_u[:-1][:, None, :], update=lambda d: -half() * d.B[:-1]),
        Term(row, tr.col_u[1:][:, None, :], update=lambda d: -half() * d.B[1:]),
    ]
    if tr.virtual_control:
        terms.append(Term(np.arange(N * nx), tr.col_nu.ravel(), -1.0))

    def rhs(d: SubproblemData) -> Array:
        """The trapezoid's defect of the reference on the current grid."""
        h = tr.h
        c = d.f - np.einsum("kjm,km->kj", d.B, d.u_ref)
        out = -(d.x_ref[1:] - d.x_ref[:-1]) + 0.5 * h[:, None] * (c[:-1] + c[1:])
        if d.defect is not None:  # deferred correction: the exact interval map at the reference
            out = out + d.defect
        return out.ravel()

    return RowBlock("dynamics", "zero", N * nx, terms, rhs=rhs)


def row_blocks(tr: EnergyTrapezoid) -> list[RowBlock[SubproblemData]]:
    """Every row block of the subproblem, in row order."""
    K, N, nx, S = tr.K, tr.N, tr.nx, tr.S
    fixed = [t for t in tr.terminal if t.kind == "fixed"]
    states = np.array([t.state for t in fixed], dtype=np.int64)
    values = np.array([t.value for t in fixed], dtype=float)
    blocks = [
        dynamics_block(tr),
        RowBlock(
            "initial",
            "zero",
            nx,
            (Term(np.arange(nx), tr.col_x[0], 1.0),),
            rhs=lambda d: (d.x0 - d.x_ref[0]) / S,
        ),
        RowBlock(
            "terminal_fixed",
            "zero",
            len(fixed),
            (Term(np.arange(len(fixed)), tr.col_x[-1, states], 1.0),),
            rhs=lambda d: (values - d.x_ref[-1, states]) / S[states],
        ),
    ]
    if tr.path_limits:  # r >= r_min: -S_r dx_r <= r_bar - r_min
        blocks.append(
            RowBlock(
                "path",
                "nonneg",
                K,
                (Term(np.arange(K), tr.col_x[:, 0], -S[0]),),
                rhs=lambda d: d.x_ref[:, 0] - _radius_lower(d),
            )
        )
    blocks.append(  # u1 >= cos sigma_max
        RowBlock("bank", "nonneg", K, (Term(np.arange(K), tr.col_u[:, 0], -1.0),), b=-tr.bank_cos)
    )
    ranges = [t for t in tr.terminal if t.kind == "range"]
    blocks.append(soft_block(tr.soft, tr.col_x[-1], tr.col_soft, S, _last_node))
    blocks.append(range_block(ranges, tr.col_x[-1], S, _last_node))
    if tr.bank_rate_rows:  # |sigma_{i+1} - sigma_i| <= cap_i, sigma linearized at the reference
        rows_i = np.arange(N)[:, None]
        pair = np.concatenate([rows_i, N + rows_i])

        def coef(d: SubproblemData, first: bool) -> Array:
            """t_{i+1} on u_{i+1} and -t_i on u_i (then negated for the lower rows)."""
            t = _bank_tangents(d)
            c = t[1:] if first else -t[:-1]
            return np.concatenate([c, -c])

        blocks.append(
            RowBlock(
                "bank_rate",
                "nonneg",
                2 * N,
                (
                    Term(pair, np.tile(tr.col_u[1:], (2, 1)), update=lambda d: coef(d, True)),
                    Term(pair, np.tile(tr.col_u[:-1], (2, 1)), update=lambda d: coef(d, False)),
                ),
                rhs=_bank_step_rhs,
            )
        )
    if tr.virtual_control:  # -mu <= nu <= mu
        rows = np.arange(N * nx)
        nu, mu = tr.col_nu.ravel(), tr.col_mu.ravel()
        blocks.append(
            RowBlock(
                "virtual_control",
                "nonneg",
                2 * N * nx,
                (
                    Term(rows, nu, 1.0),
                    Term(rows, mu, -1.0),
                    Term(N * nx + rows, nu, -1.0),
                    Term(N * nx + rows, mu, -1.0),
                ),
            )
        )
    cone = 3 * np.arange(K)[:, None] + np.array([1, 2])[None, :]  # (1, u1, u2) in the cone
    blocks.append(
        RowBlock(
            "control_norm",
            "soc",
            3 * K,
            (Term(cone, tr.col_u, -1.0),),
            b=np.tile([1.0, 0.0, 0.0], K),
            soc_dim=3,
        )
    )
    return blocks
