"""Constraints between the nodes of the time-domain SCP, carried through the exact FOH maps.

On interval k the state at an interior substep tau_j is, to first order,
x(tau_j) = x_bar(tau_j) + Phi_j dz_k + B-_j dw_k + B+_j dw_{k+1} + S_j ds_k
(transcription.foh_exact, ``InnerSamples``). A constraint g(x) <= 0 sampled there is linearized
through these maps at the sample where the reference comes closest to (or furthest past) the
bound: one row per interval and constraint, on the variables of that interval only.
"""

from __future__ import annotations

import numpy as np

from worker.solver.transcription.foh_exact import InnerSamples
from worker.solver.transcription.foh_subproblem import InnerRows

Array = np.ndarray


def rows_at_worst_sample(g: Array, grad: Array, samples: InnerSamples) -> InnerRows:
    """Rows at the worst sample of each interval and constraint.

    ``g`` (N, J, m): constraint values (<= 0 is feasible) at the J interior samples of the N
    intervals; ``grad`` (N, J, m, 7): their gradients in the state.
    """
    n, _, m = g.shape
    worst = np.argmax(g, axis=1)  # (N, m)
    kk = np.arange(n)[:, None]
    cc = np.arange(m)[None, :]
    gw = grad[kk, worst, cc]  # (N, m, 7)
    return InnerRows(
        g=g[kk, worst, cc],
        c_z=np.einsum("nmi,nmij->nmj", gw, samples.Phi[kk, worst]),
        c_wm=np.einsum("nmi,nmi->nm", gw, samples.Bm[kk, worst]),
        c_wp=np.einsum("nmi,nmi->nm", gw, samples.Bp[kk, worst]),
        c_s=np.einsum("nmi,nmi->nm", gw, samples.S[kk, worst]),
    )


def stack_rows(parts: list[InnerRows]) -> InnerRows:
    """Between-node rows of several kinds (path limits, zones) side by side on the constraint
    axis."""
    return InnerRows(
        g=np.concatenate([r.g for r in parts], axis=1),
        c_z=np.concatenate([r.c_z for r in parts], axis=1),
        c_wm=np.concatenate([r.c_wm for r in parts], axis=1),
        c_wp=np.concatenate([r.c_wp for r in parts], axis=1),
        c_s=np.concatenate([r.c_s for r in parts], axis=1),
    )
