"""Curvature of the exact FOH interval maps: the Lagrangian Hessian blocks of the SQP step.

The subproblem's stitched dynamics x_{k+1} = Phi_k(v_k) linearize the interval map Phi_k about
the reference, v_k = (z_k, w_k, w_{k+1}[, s_k]). With the constraint multipliers y_k of the last
subproblem, the dynamics contribute sum_k y_k . (x_{k+1} - Phi_k(v_k)) to the Lagrangian, whose
Hessian in v_k is -sum_i y_k,i d2 Phi_k,i / dv_k2: the curvature a first-order SCP leaves out
(Nocedal & Wright, Numerical Optimization, 2nd ed., sec. 18.1, the SQP step; the per-interval
blocks are those of multiple shooting, Bock & Plitt 1984). Each block is the forward difference of
the maps' Jacobians (A, B-, B+, S of ``foh_exact``) along each interval variable, all copies of all
intervals integrated in one batch; ``convexify`` keeps the subproblem a convex QP.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from worker.solver.forces import VehicleForces
from worker.solver.models.bank_state_compiled import compiled_parameters, float_arrays
from worker.solver.models.bank_state_sweeps import lagrangian_hessian_kernel
from worker.solver.transcription.foh_exact import Dynamics, IntervalMaps, interval_maps

Array = np.ndarray


def _jacobian(maps: IntervalMaps, with_interval: bool) -> Array:
    """[Phi | B- | B+ (| S)] of every interval, (M, 7, nb)."""
    jac = maps.jacobian
    return jac if with_interval else jac[:, :, :-1]


def lagrangian_hessian(
    z: Array,
    w: Array,
    s: Array,
    forces: VehicleForces,
    omega: float,
    weights: Array,
    steps: Array,
    substeps: int,
    with_interval: bool,
    *,
    compiled: bool = True,
    dynamics: Dynamics | None = None,
) -> Array | None:
    """Hessian blocks (N, nb, nb) of sum_k weights_k . Phi_k(v_k) in the interval variables.

    ``weights`` (N, 7) multiply the end states (the negated multipliers of the dynamics rows, in
    nondimensional state units); ``steps`` (nb,) are the difference steps of z_k (7), w_k, w_{k+1}
    and, ``with_interval``, s_k. None when a perturbed integration is not finite (a reference
    that leaves the atmosphere model's range), so the caller can take a first-order step.
    ``dynamics``: another model (numpy form) with rates ``w`` (K, m): m columns each for w_k
    and w_{k+1}.
    """
    n, nz = s.size, z.shape[1]
    m = 1 if w.ndim == 1 else w.shape[1]
    nb = nz + 2 * m + (1 if with_interval else 0)
    params = compiled_parameters(forces, omega) if compiled and dynamics is None else None
    if params is not None:  # the same differences, of adjoint gradients (models.bank_state_sweeps)
        xa, wa, wb, sa, la, ha = float_arrays(z[:-1], w[:-1], w[1:], s, weights, steps)
        hess = lagrangian_hessian_kernel(xa, wa, wb, sa, la, ha, nb, params, substeps)
        return hess if bool(np.all(np.isfinite(hess))) else None
    copies = nb + 1  # the unperturbed intervals, then one perturbed copy per variable
    x0 = np.tile(z[:-1], (copies, 1))
    tiles = (copies,) if m == 1 else (copies, 1)
    w0 = np.tile(w[:-1], tiles)
    w1 = np.tile(w[1:], tiles)
    ss = np.tile(s, copies)
    for j in range(nb):
        block = slice((j + 1) * n, (j + 2) * n)
        if j < nz:
            x0[block, j] += steps[j]
        elif j < nz + 2 * m:
            target = w0 if j < nz + m else w1
            c = (j - nz) % m
            if m == 1:
                target[block] += steps[j]
            else:
                target[block, c] += steps[j]
        else:
            ss[block] += steps[j]
    with np.errstate(all="ignore"):
        maps = interval_maps(
            x0, w0, w1, ss, forces, omega, substeps, compiled=False, dynamics=dynamics
        )
        jac = _jacobian(maps, with_interval)
        jac = jac.reshape(copies, n, nz, nb)
        # column j: d/dv_j of J_k' weights_k (the gradient of weights . Phi_k)
        grad = np.einsum("cnij,ni->cnj", jac, weights)
        hess = (grad[1:] - grad[0][None]) / steps[:, None, None]  # (nb: column, N, nb: row)
    if not np.all(np.isfinite(hess)):
        return None
    hess = np.transpose(hess, (1, 2, 0))  # (N, row, column)
    return 0.5 * (hess + np.transpose(hess, (0, 2, 1)))


def convexify(blocks: Array, floor: float = 0.0) -> Array:
    """The blocks with every eigenvalue below ``floor`` raised to it (symmetric, PSD for floor >=
    0): the nearest convex model of each block in the Frobenius norm (Higham 1988)."""
    lam, vec = np.linalg.eigh(blocks)
    lam = np.maximum(lam, floor)
    return np.matmul(vec * lam[:, None, :], np.transpose(vec, (0, 2, 1)))


@dataclass(frozen=True)
class BlockLayout:
    """How the curvature blocks enter the subproblem's P: the block variables kept (all but
    the longitude, which enters no rate, so its row and column are zero), their scales (the
    subproblem's variable units) and the (row, column) pairs of the upper triangle stored."""

    keep: Array  # (k,) int64 indices into the nb block variables
    scale: Array  # (k,) float64
    rows: Array  # (T,) int64 indices into keep
    cols: Array  # (T,) int64

    def values(self, hessian: Array) -> Array:
        """The P entries (N * T,) of blocks (N, nb, nb): scaled, convexified, upper triangles."""
        k = self.keep
        scaled = hessian[:, k[:, None], k] * self.scale[:, None] * self.scale[None, :]
        upper: Array = convexify(scaled)[:, self.rows, self.cols]
        return upper.ravel()


@njit(cache=True, nogil=True, error_model="numpy")
def _convexified_values(
    hess: Array, keep: Array, scale: Array, rows: Array, cols: Array
) -> tuple[Array, bool]:
    """``BlockLayout.values`` compiled, with a flag that is False when a block is not finite."""
    n_int = hess.shape[0]
    k = keep.size
    out = np.empty((n_int, rows.size))
    block = np.empty((k, k))
    for n in range(n_int):
        for i in range(k):
            for j in range(k):
                block[i, j] = hess[n, keep[i], keep[j]] * scale[i] * scale[j]
        if not np.all(np.isfinite(block)):
            return out.ravel(), False
        lam, vec = np.linalg.eigh(block)
        lam = np.maximum(lam, 0.0)
        for t in range(rows.size):
            i, j = rows[t], cols[t]
            acc = 0.0
            for m in range(k):
                acc += vec[i, m] * lam[m] * vec[j, m]
            out[n, t] = acc
    return out.ravel(), True


@njit(cache=True, nogil=True, error_model="numpy")
def curvature_kernel(
    x0: Array,
    w0: Array,
    w1: Array,
    s: Array,
    weights: Array,
    steps: Array,
    nb: int,
    p: Array,
    substeps: int,
    keep: Array,
    scale: Array,
    rows: Array,
    cols: Array,
) -> tuple[Array, bool]:
    """The Hessian blocks and their convexified P entries in one call without the GIL, so the
    whole of it can overlap other work (``side_thread``)."""
    hess = lagrangian_hessian_kernel(x0, w0, w1, s, weights, steps, nb, p, substeps)
    return _convexified_values(hess, keep, scale, rows, cols)


def convexified_curvature(
    z: Array,
    w: Array,
    s: Array,
    forces: VehicleForces,
    omega: float,
    weights: Array,
    steps: Array,
    substeps: int,
    layout: BlockLayout,
    *,
    compiled: bool = True,
    dynamics: Dynamics | None = None,
) -> Array | None:
    """The P entries of the convexified curvature blocks (``lagrangian_hessian`` through
    ``layout``), or None when a perturbed integration is not finite. ``steps`` has one entry
    per block variable (9 or 10: with the interval length; nz + 2 m (+ 1) for m controls)."""
    nb = steps.size
    params = compiled_parameters(forces, omega) if compiled and dynamics is None else None
    if params is not None:
        xa, wa, wb, sa, la, ha = float_arrays(z[:-1], w[:-1], w[1:], s, weights, steps)
        lay = layout
        values, ok = curvature_kernel(
            xa, wa, wb, sa, la, ha, nb, params, substeps, lay.keep, lay.scale, lay.rows, lay.cols
        )
        return values if ok else None
    m = 1 if w.ndim == 1 else w.shape[1]
    hess = lagrangian_hessian(
        z,
        w,
        s,
        forces,
        omega,
        weights,
        steps,
        substeps,
        nb == z.shape[1] + 2 * m + 1,
        compiled=False,
        dynamics=dynamics,
    )
    return None if hess is None else layout.values(hess)


def warm_up(params: Array) -> None:
    """Compile (or load from the cache) ``curvature_kernel`` on one interval with the argument
    types ``convexified_curvature`` passes; ``params``: ``compiled_parameters``' layout. Called by
    ``worker.solver.warmup.warm_up``."""
    x0 = np.array([[1.015, 0.0, 0.0, 0.9, 0.0, 0.0, 0.3]])
    w = np.zeros(1)
    nb = x0.shape[1] + 3
    steps = np.full(nb, 1e-5)
    keep = np.array([j for j in range(nb) if j != 1], dtype=np.int64)
    rows, cols = (a.astype(np.int64) for a in np.triu_indices(keep.size))
    curvature_kernel(
        x0,
        w,
        w,
        np.full(1, 0.01),
        x0.copy(),
        steps,
        nb,
        params,
        2,
        keep,
        steps[keep],
        rows,
        cols,
    )
