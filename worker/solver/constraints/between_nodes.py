"""Constraints between the nodes of the time-domain SCP, carried through the exact FOH maps.

On interval k the state at an interior substep tau_j is, to first order,
x(tau_j) = x_bar(tau_j) + Phi_j dz_k + B-_j dw_k + B+_j dw_{k+1} + S_j ds_k
(transcription.foh_exact, ``InnerSamples``). A constraint g(x) <= 0 sampled there becomes one
row per interval and constraint, on the variables of that interval only: the smooth maximum
(Kreisselmeier-Steinhauser function) of its interior samples, linearized through these maps.
Taking the single worst sample instead makes the row jump between samples from one iteration to
the next, and the SCP then cycles between two points instead of converging.
"""

from __future__ import annotations

import numpy as np

from worker.solver.transcription.foh_exact import InnerSamples, IntervalMaps
from worker.solver.transcription.foh_subproblem import InnerRows

Array = np.ndarray


def with_end_points(z: Array, maps: IntervalMaps) -> InnerSamples:
    """The interior samples of every interval with its two end points added: the start node
    (x = z_k, identity map) and the propagated end (the interval map itself, = z_{k+1} at
    convergence). One smooth maximum then covers the nodes too, so the binding point can move
    between a node and the interior without the row switching."""
    assert maps.inner is not None
    inner = maps.inner
    n, _, nz = inner.x.shape
    zero = np.zeros((n, 1, nz))
    return InnerSamples(
        x=np.concatenate([z[:-1, None, :], inner.x, maps.x_prop[:, None, :]], axis=1),
        Phi=np.concatenate(
            [np.broadcast_to(np.eye(nz), (n, 1, nz, nz)), inner.Phi, maps.Phi[:, None]], axis=1
        ),
        Bm=np.concatenate([zero, inner.Bm, maps.Bm[:, None, :]], axis=1),
        Bp=np.concatenate([zero, inner.Bp, maps.Bp[:, None, :]], axis=1),
        S=np.concatenate([zero, inner.S, maps.S[:, None, :]], axis=1),
    )


def smooth_max_rows(g: Array, grad: Array, samples: InnerSamples, width: Array) -> InnerRows:
    """Rows of the smooth maximum over each interval's interior samples, per constraint.

    ``g`` (N, J, m): constraint values (<= 0 is feasible) at the J interior samples of the N
    intervals; ``grad`` (N, J, m, 7): their gradients in the state; ``width`` (m,): the
    smoothing width d of g_KS = g_max + d ln sum_j exp((g_j - g_max) / d), which lies between
    g_max and g_max + d ln J (so the row is conservative by at most d ln J) and whose gradient
    is the softmax-weighted mean of the samples' gradients.
    """
    d = np.asarray(width, dtype=float)[None, None, :]
    gmax = np.max(g, axis=1, keepdims=True)  # (N, 1, m)
    e = np.exp((g - gmax) / d)
    total = np.sum(e, axis=1)  # (N, m)
    weight = e / total[:, None, :]  # (N, J, m), sums to 1 over J
    wg = weight[..., None] * grad  # (N, J, m, 7)
    # [Phi | B- | B+ | S] of every sample, (N, J, 7, 10): one batched product gives all four
    maps = np.concatenate(
        [samples.Phi, samples.Bm[..., None], samples.Bp[..., None], samples.S[..., None]], axis=-1
    )
    c = np.matmul(wg, maps).sum(axis=1)  # (N, m, 10)
    nz = samples.Phi.shape[-1]
    return InnerRows(
        g=gmax[:, 0, :] + d[0] * np.log(total),
        c_z=c[:, :, :nz],
        c_wm=c[:, :, nz],
        c_wp=c[:, :, nz + 1],
        c_s=c[:, :, nz + 2],
        worst=gmax[:, 0, :],
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
        worst=np.concatenate([r.worst for r in parts], axis=1),
    )
