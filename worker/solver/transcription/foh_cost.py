"""The objective of the time-domain subproblem (paper 002 Problem 2): its P pattern and the
values of P and q.

The quadratic part is diagonal on (dz, dw, ds) — the penalized trust region (eq. 28) and the
separable penalties of the objective — plus, for the SQP step, one convexified Lagrangian Hessian
block per interval on (dz_k, dw_k, dw_{k+1}[, ds_k]) with the longitude left out (it enters no
rate, paper 000 eq. 1, so its row and column are zero). The linear part holds the objective's
gradients and the weights of the soft-terminal slacks and of the virtual-control buffers.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from worker.solver.conic import SparseAssembler
from worker.solver.transcription.foh_data import SubproblemData
from worker.solver.transcription.foh_hessian import BlockLayout

if TYPE_CHECKING:
    from worker.solver.transcription.foh_subproblem import FohSubproblem

Array = np.ndarray


class FohCost:
    """P on a pattern fixed at construction (its diagonal, then the curvature blocks; overlaps
    summed) and the per-iteration values of P and q."""

    def __init__(self, sub: FohSubproblem) -> None:
        self.sub = sub
        nb = sub.block_cols.shape[1]
        longitude = sub.state_index[1]
        keep = np.array([j for j in range(nb) if j != longitude], dtype=np.int64)
        upper = np.triu_indices(keep.size)
        self.curvature_layout = BlockLayout(
            keep=keep,
            scale=np.ascontiguousarray(sub.block_scale[keep], dtype=np.float64),
            rows=upper[0].astype(np.int64),
            cols=upper[1].astype(np.int64),
        )
        self.n_upper = upper[0].size
        self.n_quad = sub.col_s.size + sub.K * (sub.nz + sub.controls)  # z, w and s
        diag = np.arange(self.n_quad)
        p_rows, p_cols = [diag], [diag]
        self.n_span = 0
        if sub.free_final_time:  # the rank-one final-time term on every pair of intervals
            s_upper = np.triu_indices(sub.N)
            p_rows.append(sub.col_s[s_upper[0]])
            p_cols.append(sub.col_s[s_upper[1]])
            self.n_span = s_upper[0].size
        if sub.hessian_blocks:  # one upper triangle per interval block
            curved_cols = sub.block_cols[:, keep]
            a = curved_cols[:, upper[0]].ravel()
            b = curved_cols[:, upper[1]].ravel()
            p_rows.append(np.minimum(a, b))
            p_cols.append(np.maximum(a, b))
        self.P_asm = SparseAssembler(
            np.concatenate(p_rows), np.concatenate(p_cols), (sub.n, sub.n), upper_triangular=True
        )

    def diagonal(self, d: SubproblemData) -> Array:
        """P's triplet values with the curvature blocks left zero: 2 w_tr (plus the separable
        penalties' 2 Q Dz^2 on z), and 2 w_tr2 on the interval lengths; with a free final time
        the intervals' mean change m is weighted by w_trT instead: w_tr2 |ds - m|^2 + w_trT N m^2
        = w_tr2 |ds|^2 + (w_trT - w_tr2) (sum ds)^2 / N, a rank-one term on every pair."""
        sub = self.sub
        K, nz, nw = sub.K, sub.nz, sub.K * sub.controls
        n_blocks = sub.N * self.n_upper if sub.hessian_blocks else 0
        p = np.zeros(self.n_quad + self.n_span + n_blocks)
        pz = p[: K * nz].reshape(K, nz)
        pz[:] = 2.0 * sub.w_tr + 2.0 * d.quad_z * sub.Dz[None, :] ** 2
        p[K * nz : K * nz + nw] = 2.0 * sub.w_tr
        p[K * nz + nw : self.n_quad] = 2.0 * sub.w_tr2
        if self.n_span:  # w_tr2 on the sliding only; the final time's change at w_trT
            p[self.n_quad : self.n_quad + self.n_span] = 2.0 * (sub.w_trT - sub.w_tr2) / sub.N
        return p

    def interval_trust(self, ds: Array) -> float:
        """The interval-trust term of the cost at the scaled interval step ``ds`` (what the P
        entries of ``diagonal`` weigh, halved as 0.5 x'Px is)."""
        sub = self.sub
        value = sub.w_tr2 * float(np.sum(ds**2))
        if self.n_span and ds.size:
            value += (sub.w_trT - sub.w_tr2) * float(np.sum(ds)) ** 2 / ds.size
        return value

    def P(self, p: Array, curvature: Array | None) -> sp.csc_matrix:
        """P from the diagonal values ``p`` and the curvature blocks' values (None: none)."""
        if self.sub.hessian_blocks and curvature is not None:
            p[self.n_quad + self.n_span :] = curvature
        return self.P_asm.assemble(p)

    def q(self, d: SubproblemData) -> Array:
        """The linear cost: gradients of the objective and of its penalties on (dz, ds), the
        soft-terminal weights and the buffer weight."""
        sub = self.sub
        Dz = sub.Dz[None, :]
        values = {
            "z": d.grad_z * Dz + 2.0 * d.quad_z * (d.z - d.quad_center) * Dz,
            "soft": sub.soft_weights,
            "buffer": sub.w_buf,
        }
        if sub.adaptive:
            values["s"] = d.grad_s * sub.Ds
        if d.grad_w is not None:
            values["w"] = d.grad_w * sub.Dw
        return sub.columns.vector(values)
