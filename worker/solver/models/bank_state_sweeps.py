"""Compiled sweeps of the bank-state model built on its point rates: the exact FOH maps of every
interval, the discrete-adjoint end gradients and the Lagrangian Hessian blocks (paper 002).

``interval_maps_kernel`` integrates the augmented system [x | Phi | B- | B+ | S] of
``transcription.foh_exact`` by RK4; ``lagrangian_hessian_kernel`` differences adjoint gradients
of the same RK4 steps (``transcription.foh_hessian``). ``warm_up`` compiles (or loads) the
model's kernels on a tiny case; ``worker.solver.warmup`` warms every kernel of the solver.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from worker.solver.models.bank_state_compiled import AUGMENTED_COLUMNS as AUG
from worker.solver.models.bank_state_compiled import (
    LONGITUDE,
    N,
    chain_kernel,
    point_rates,
    propagate_kernel,
)

Array = np.ndarray


@njit(cache=True, nogil=True, error_model="numpy")
def _augmented_rhs(
    tau: float,
    y: Array,
    w0: float,
    w1: float,
    s: float,
    p: Array,
    scratch: Array,
    a: Array,
    out: Array,
) -> None:
    """d/dtau of [x | Phi | B- | B+ | S] on one interval (foh_exact's module docstring);
    ``scratch`` (2, 7) holds the state and its rates."""
    x = scratch[0]
    f = scratch[1]
    for i in range(N):
        x[i] = y[i, 0]
    point_rates(x, (1.0 - tau) * w0 + tau * w1, s, p, f, a, True)
    # A y on the structural nonzeros of A only (``point_rates``): 28 of the 42 products per column
    for j in range(1, AUG):
        y0, y2, y3, y4, y5, y6 = y[0, j], y[2, j], y[3, j], y[4, j], y[5, j], y[6, j]
        out[0, j] = a[0, 3] * y3 + a[0, 4] * y4
        out[1, j] = a[1, 0] * y0 + a[1, 2] * y2 + a[1, 3] * y3 + a[1, 4] * y4 + a[1, 5] * y5
        out[2, j] = a[2, 0] * y0 + a[2, 3] * y3 + a[2, 4] * y4 + a[2, 5] * y5
        out[3, j] = a[3, 0] * y0 + a[3, 2] * y2 + a[3, 3] * y3 + a[3, 4] * y4 + a[3, 5] * y5
        out[4, j] = (
            a[4, 0] * y0 + a[4, 2] * y2 + a[4, 3] * y3 + a[4, 4] * y4 + a[4, 5] * y5 + a[4, 6] * y6
        )
        out[5, j] = (
            a[5, 0] * y0 + a[5, 2] * y2 + a[5, 3] * y3 + a[5, 4] * y4 + a[5, 5] * y5 + a[5, 6] * y6
        )
    for i in range(N - 1):
        out[i, 0] = s * f[i]
        out[i, AUG - 1] += f[i]
    # row 6 (the bank angle): A has a zero row, B = dF/dw = (0, ..., 0, s), S = f
    out[6, 0] = s * f[6]
    for j in range(1, AUG):
        out[6, j] = 0.0
    out[6, N + 1] = (1.0 - tau) * s
    out[6, N + 2] = tau * s
    out[6, AUG - 1] = f[6]


@njit(cache=True, nogil=True, error_model="numpy")
def interval_maps_kernel(
    x0: Array, w0: Array, w1: Array, s: Array, p: Array, substeps: int, keep: bool
) -> tuple[Array, Array]:
    """The augmented FOH system of every interval after RK4 over tau in [0, 1] (M, 7, 11) and,
    with ``keep``, at every substep, both ends included (M, substeps + 1, 7, 11); the same steps
    as ``foh_exact._rk4_unit_interval``."""
    m_count = s.size
    out = np.empty((m_count, N, AUG))
    kept = np.empty((m_count, substeps + 1 if keep else 0, N, AUG))
    f = np.empty((2, N))
    a = np.zeros((N, N))  # point_rates writes only its structural nonzeros
    k1 = np.empty((N, AUG))
    k2 = np.empty((N, AUG))
    k3 = np.empty((N, AUG))
    k4 = np.empty((N, AUG))
    tmp = np.empty((N, AUG))
    y = np.empty((N, AUG))
    h = 1.0 / substeps
    for m in range(m_count):
        y[:, :] = 0.0
        for i in range(N):
            y[i, 0] = x0[m, i]
            y[i, 1 + i] = 1.0
        if keep:
            kept[m, 0] = y
        tau = 0.0
        for step in range(substeps):
            _augmented_rhs(tau, y, w0[m], w1[m], s[m], p, f, a, k1)
            _axpy(y, 0.5 * h, k1, tmp)
            _augmented_rhs(tau + 0.5 * h, tmp, w0[m], w1[m], s[m], p, f, a, k2)
            _axpy(y, 0.5 * h, k2, tmp)
            _augmented_rhs(tau + 0.5 * h, tmp, w0[m], w1[m], s[m], p, f, a, k3)
            _axpy(y, h, k3, tmp)
            _augmented_rhs(tau + h, tmp, w0[m], w1[m], s[m], p, f, a, k4)
            c = h / 6.0
            for i in range(N):
                for j in range(AUG):
                    y[i, j] = y[i, j] + c * (k1[i, j] + 2.0 * k2[i, j] + 2.0 * k3[i, j] + k4[i, j])
            tau += h
            if keep:
                kept[m, step + 1] = y
        out[m] = y
    return out, kept


@njit(cache=True, nogil=True, error_model="numpy")
def _axpy(y: Array, c: float, k: Array, out: Array) -> None:
    """out = y + c k, elementwise, without a temporary."""
    for i in range(y.shape[0]):
        for j in range(y.shape[1]):
            out[i, j] = y[i, j] + c * k[i, j]


@njit(cache=True, nogil=True, error_model="numpy")
def _end_gradient(
    x0: Array,
    w0: float,
    w1: float,
    s: float,
    lam0: Array,
    p: Array,
    substeps: int,
    a_st: Array,
    f_st: Array,
    work: Array,
    out: Array,
) -> None:
    """The gradient of lam0 . x(1) in (x0, w0, w1, s) on one interval, into ``out`` (10,).

    x(1) is the RK4 end state of ``propagate_kernel``; the gradient is the discrete adjoint of
    those steps (reverse mode through each stage), so it equals lam0' [Phi | B- | B+ | S] of
    ``interval_maps_kernel`` to rounding at a fraction of the cost: a 7-vector is carried back
    instead of a 7 x 10 sensitivity forward. ``a_st`` (4 substeps, 7, 7) and ``f_st``
    (4 substeps, 7) hold each stage's s df/dz and f; ``work`` (13, 7) is scratch.
    """
    h = 1.0 / substeps
    x, xt, f, lam, yb = work[0], work[1], work[2], work[3], work[4]
    k = work[5:9]
    kb = work[9:13]
    x[:] = x0
    offsets = (0.0, 0.5, 0.5, 1.0)
    tau = 0.0
    for step in range(substeps):
        for q in range(4):
            if q == 0:
                xt[:] = x
            else:
                c = h if q == 3 else 0.5 * h
                for i in range(N):
                    xt[i] = x[i] + c * k[q - 1, i]
            tq = tau + offsets[q] * h
            st = 4 * step + q
            point_rates(xt, (1.0 - tq) * w0 + tq * w1, s, p, f, a_st[st], True)
            f_st[st] = f
            for i in range(N):
                k[q, i] = s * f[i]
        for i in range(N):
            x[i] = x[i] + (h / 6.0) * (k[0, i] + 2.0 * k[1, i] + 2.0 * k[2, i] + k[3, i])
        tau += h
    lam[:] = lam0
    g_w0 = 0.0
    g_w1 = 0.0
    g_s = 0.0
    weights = (h / 6.0, h / 3.0, h / 3.0, h / 6.0)
    back = (0.0, 0.5 * h, 0.5 * h, h)  # how stage q's input depends on stage q-1's slope
    for step in range(substeps - 1, -1, -1):
        tau -= h
        for q in range(4):
            for i in range(N):
                kb[q, i] = weights[q] * lam[i]
        for q in range(3, -1, -1):
            st = 4 * step + q
            tq = tau + offsets[q] * h
            # k_q = s f(x_q, w(tau_q)): back through A (= s df/dz), B = s e_sigma, S = f
            # yb = A' kb on the structural nonzeros of A (``point_rates``; row 6 and column 1 zero)
            a = a_st[st]
            k0, k1, k2, k3, k4, k5 = kb[q, 0], kb[q, 1], kb[q, 2], kb[q, 3], kb[q, 4], kb[q, 5]
            yb[0] = a[1, 0] * k1 + a[2, 0] * k2 + a[3, 0] * k3 + a[4, 0] * k4 + a[5, 0] * k5
            yb[1] = 0.0
            yb[2] = a[1, 2] * k1 + a[3, 2] * k3 + a[4, 2] * k4 + a[5, 2] * k5
            yb[3] = (a[0, 3] * k0 + a[1, 3] * k1 + a[2, 3] * k2 + a[3, 3] * k3 + a[4, 3] * k4) + a[
                5, 3
            ] * k5
            yb[4] = (a[0, 4] * k0 + a[1, 4] * k1 + a[2, 4] * k2 + a[3, 4] * k3 + a[4, 4] * k4) + a[
                5, 4
            ] * k5
            yb[5] = a[1, 5] * k1 + a[2, 5] * k2 + a[3, 5] * k3 + a[4, 5] * k4 + a[5, 5] * k5
            yb[6] = a[4, 6] * k4 + a[5, 6] * k5
            g_w0 += (1.0 - tq) * s * kb[q, 6]
            g_w1 += tq * s * kb[q, 6]
            for i in range(N):
                g_s += f_st[st, i] * kb[q, i]
                lam[i] += yb[i]
            if q > 0:
                for i in range(N):
                    kb[q - 1, i] += back[q] * yb[i]
    out[:N] = lam
    out[N] = g_w0
    out[N + 1] = g_w1
    out[N + 2] = g_s


@njit(cache=True, nogil=True, error_model="numpy")
def lagrangian_hessian_kernel(
    x0: Array,
    w0: Array,
    w1: Array,
    s: Array,
    weights: Array,
    steps: Array,
    nb: int,
    p: Array,
    substeps: int,
) -> Array:
    """Blocks (N, nb, nb) of the Hessian of weights_k . x_k(1) in (x0, w0, w1[, s]) of every
    interval: forward differences of ``_end_gradient`` along each variable, symmetrized (the
    compiled form of ``foh_hessian.lagrangian_hessian``)."""
    n_int = s.size
    hess = np.empty((n_int, nb, nb))
    base = np.empty(N + 3)
    pert = np.empty(N + 3)
    a_st = np.zeros((4 * substeps, N, N))  # point_rates writes only its structural nonzeros
    f_st = np.empty((4 * substeps, N))
    work = np.empty((13, N))
    xp = np.empty(N)
    for n in range(n_int):
        _end_gradient(x0[n], w0[n], w1[n], s[n], weights[n], p, substeps, a_st, f_st, work, base)
        for j in range(nb):
            if j == LONGITUDE:  # no rate depends on the longitude: its row and column are zero
                for i in range(nb):
                    hess[n, i, j] = 0.0
                continue
            xp[:] = x0[n]
            wa, wb, sn = w0[n], w1[n], s[n]
            if j < N:
                xp[j] += steps[j]
            elif j == N:
                wa += steps[j]
            elif j == N + 1:
                wb += steps[j]
            else:
                sn += steps[j]
            _end_gradient(xp, wa, wb, sn, weights[n], p, substeps, a_st, f_st, work, pert)
            for i in range(nb):
                hess[n, i, j] = (pert[i] - base[i]) / steps[j]
        for i in range(nb):
            for j in range(i + 1, nb):
                mean = 0.5 * (hess[n, i, j] + hess[n, j, i])
                hess[n, i, j] = mean
                hess[n, j, i] = mean
    return hess


def warm_up(params: Array) -> None:
    """Compile (or load from the cache) the model's kernels on one interval with the argument
    types the transcription passes; ``params``: ``compiled_parameters``' layout. Called by
    ``worker.solver.warmup.warm_up``."""
    x0 = np.array([[1.015, 0.0, 0.0, 0.9, 0.0, 0.0, 0.3]])
    w = np.zeros(1)
    s = np.full(1, 0.01)
    interval_maps_kernel(x0, w, w, s, params, 2, True)
    propagate_kernel(x0, w, w, s, params, 2, True)
    chain_kernel(x0, s, params, 2)
