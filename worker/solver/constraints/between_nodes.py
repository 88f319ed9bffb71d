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

The smooth maximum g_KS = g_max + d ln sum_j exp((g_j - g_max) / d) exceeds the worst sample by
its offset d ln sum_j exp(...), between 0 and d ln J. Kept (``exact=False``), the row is
conservative by that offset at convergence, which on a fine mesh (near-equal samples) tends to
its bound d ln J and biases the optimum. Removed at the reference (``exact=True``, the default
of the method), the row's value is the worst sample itself and only its gradient is smoothed:
g_max(ref) + grad g_KS . dx <= 0, the linearization of g_KS minus its offset frozen at the
reference. At a converged reference (dx = 0) it holds g_max <= 0 exactly, neither conservative
nor optimistic at the samples, and with d -> 0 it would be the single worst sample's row; what
may remain between the samples is the sampling error, which the verification judges.
"""

from __future__ import annotations

import numpy as np

from worker.solver.constraints.path_compiled import smooth_max_kernel
from worker.solver.transcription.foh_data import InnerRows
from worker.solver.transcription.foh_exact import IntervalSamples

Array = np.ndarray


def smooth_max_rows(
    g: Array, grads: dict[int, Array], samples: IntervalSamples, width: Array, *, exact: bool
) -> InnerRows:
    """Rows of the smooth maximum over each interval's samples, per constraint.

    ``g`` (N, J, m): constraint values (<= 0 is feasible) at the J samples of the N intervals;
    ``grads``: their partials (N, J, m) in each state they depend on, by state index (the
    others are zero); ``width`` (m,): the smoothing width d of
    g_KS = g_max + d ln sum_j exp((g_j - g_max) / d), which lies between g_max and
    g_max + d ln J and whose gradient is the softmax-weighted mean of the samples' gradients
    (compiled: ``path_compiled``). ``exact``: the row's value is g_max, g_KS less its offset at
    the reference (module docstring); else g_KS, conservative by at most d ln J.
    """
    states = np.array(list(grads), dtype=np.int64)
    partials = np.stack([np.asarray(grads[i], dtype=np.float64) for i in grads])
    value, c, worst = smooth_max_kernel(
        np.ascontiguousarray(g, dtype=np.float64),
        states,
        partials,
        np.ascontiguousarray(samples.augmented, dtype=np.float64),
        np.asarray(width, dtype=np.float64),
    )
    return InnerRows(g=worst.copy() if exact else value, c=c, worst=worst)


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
