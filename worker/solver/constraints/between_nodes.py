"""Constraints between the nodes of the time-domain SCP, carried through the exact FOH maps.

On interval k the state at a substep tau_j is, to first order,
x(tau_j) = x_bar(tau_j) + Phi_j dz_k + B-_j dw_k + B+_j dw_{k+1} + S_j ds_k
(transcription.foh_exact, ``IntervalSamples``). A constraint g(x) <= 0 sampled there becomes one
row per interval and constraint, on the variables of that interval only: the smooth maximum
(Kreisselmeier-Steinhauser function) of its samples, linearized through these maps. Taking the
single worst sample instead makes the row jump between samples from one iteration to the next,
and the SCP then cycles between two points instead of converging. The samples include both ends
of the interval (the node and the propagated end, = z_{k+1} at convergence), so one smooth
maximum covers the nodes too and the binding point can move between a node and the interior
without the row switching.
"""

from __future__ import annotations

import numpy as np

from worker.solver.transcription.foh_exact import IntervalSamples
from worker.solver.transcription.foh_subproblem import InnerRows

Array = np.ndarray


def smooth_max_rows(
    g: Array, grads: dict[int, Array], samples: IntervalSamples, width: Array
) -> InnerRows:
    """Rows of the smooth maximum over each interval's samples, per constraint.

    ``g`` (N, J, m): constraint values (<= 0 is feasible) at the J samples of the N intervals;
    ``grads``: their partials (N, J, m) in each state they depend on, by state index (the
    others are zero); ``width`` (m,): the smoothing width d of
    g_KS = g_max + d ln sum_j exp((g_j - g_max) / d), which lies between g_max and
    g_max + d ln J (so the row is conservative by at most d ln J) and whose gradient is the
    softmax-weighted mean of the samples' gradients.
    """
    d = np.asarray(width, dtype=float)[None, None, :]
    gmax = np.max(g, axis=1, keepdims=True)  # (N, 1, m)
    e = np.exp((g - gmax) / d)
    total = np.sum(e, axis=1)  # (N, m)
    weight = e / total[:, None, :]  # (N, J, m), sums to 1 over J
    jac = samples.jacobian  # [Phi | B- | B+ | S] (N, J, 7, 10)
    c = np.zeros((g.shape[0], g.shape[2], jac.shape[-1]))  # (N, m, 10)
    for i, partial in grads.items():  # sum over j of weight * dg/dx_i * d x_i / d(variables)
        c += np.matmul(np.transpose(weight * partial, (0, 2, 1)), jac[:, :, i, :])
    return InnerRows(g=gmax[:, 0, :] + d[0] * np.log(total), c=c, worst=gmax[:, 0, :])


def stack_rows(parts: list[InnerRows]) -> InnerRows:
    """Between-node rows of several kinds (path limits, zones) side by side on the constraint
    axis."""
    if len(parts) == 1:
        return parts[0]
    return InnerRows(
        g=np.concatenate([r.g for r in parts], axis=1),
        c=np.concatenate([r.c for r in parts], axis=1),
        worst=np.concatenate([r.worst for r in parts], axis=1),
    )
