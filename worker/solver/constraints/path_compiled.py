"""Compiled (numba) path-limit rows and between-node smooth maxima of the time-domain SCP.

``log_rows_kernel`` is ``log_path.log_path_rows`` for the force models that
``models.bank_state_compiled`` covers (exponential atmosphere, polynomial CL/CD, alpha constant
or on its velocity schedule): per point ln(p / p_max) and its partials in r and V for heat rate
(paper 000 eq. 12 with paper 004's alpha factor), dynamic pressure and load factor.
``smooth_max_kernel`` is the arithmetic of ``between_nodes.smooth_max_rows`` for any constraint.
Both replace a few dozen numpy calls on arrays of a few hundred points per SCP iteration; the
numpy forms stay the reference (``tests/unit/test_path_compiled.py`` holds them equal).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from worker.solver.models.bank_state_compiled import (
    AUGMENTED_COLUMNS,
    N,
    aero_terms,
    compiled_parameters,
)
from worker.solver.polynomial import horner
from worker.solver.problem import EntryProblem

Array = np.ndarray

# Layout of the limit parameters: which limits are on (in log_path.LIMIT_NAMES order), then
# ln k_q, the speed and density exponents, ln of each maximum, the alpha polynomial of qa
_HEAT, _QBAR, _LOAD, _LN_KQ, _NV, _NRHO, _LN_HEAT_MAX, _LN_QBAR_MAX, _LN_LOAD_MAX, _NQA = range(10)
_QA = 10


def limit_parameters(problem: EntryProblem, names: tuple[str, ...]) -> tuple[Array, Array] | None:
    """(limit parameters, force-model parameters) for ``log_rows_kernel``, or None when the force
    models have no compiled form. ``names``: the active limits (``log_path.active_limits``)."""
    forces = compiled_parameters(problem.forces, problem.omega)
    if forces is None:
        return None
    lim, heat = problem.limits, problem.heat_model
    poly = tuple(heat.alpha_polynomial or ()) if heat is not None else ()
    head = np.zeros(_QA)
    if "heat_rate" in names:
        assert heat is not None and lim.heat_max_W_m2 is not None
        head[[_HEAT, _LN_KQ, _NV, _NRHO, _LN_HEAT_MAX, _NQA]] = [
            1.0,
            math.log(heat.k_q),
            heat.velocity_exponent,
            heat.density_exponent,
            math.log(lim.heat_max_W_m2),
            len(poly),
        ]
    if "dynamic_pressure" in names:
        assert lim.dynamic_pressure_max_Pa is not None
        head[[_QBAR, _LN_QBAR_MAX]] = [1.0, math.log(lim.dynamic_pressure_max_Pa)]
    if "load_factor" in names:
        assert lim.load_factor_max_g is not None
        head[[_LOAD, _LN_LOAD_MAX]] = [1.0, math.log(lim.load_factor_max_g)]
    return np.concatenate([head, np.asarray(poly, dtype=float)]), forces


@njit(cache=True, nogil=True, error_model="numpy")
def log_rows_kernel(r: Array, v: Array, lp: Array, fp: Array) -> tuple[Array, Array, Array]:
    """ln(p / p_max) and its partials in nondimensional r and V (M, m) at the points (r, v), one
    column per active limit in heat rate, dynamic pressure, load factor order."""
    m = int(lp[_HEAT] + lp[_QBAR] + lp[_LOAD])
    n_pts = r.size
    g = np.empty((n_pts, m))
    g_r = np.empty((n_pts, m))
    g_v = np.empty((n_pts, m))
    vs, kb = fp[1], fp[2]  # speed unit and ballistic factor (``compiled_parameters``' layout)
    nqa = int(lp[_NQA])
    for k in range(n_pts):
        rk, vk = r[k], v[k]
        rho, rho_r, alpha, alpha_v, cl, dcl, cd, dcd = aero_terms(rk, vk, fp)
        col = 0
        if lp[_HEAT] == 1.0:
            qa, qa_a = 1.0, 0.0
            if nqa > 0:  # lowest order first (path_limits.HeatRateModel.alpha_factor)
                qa, qa_a = horner(lp, _QA, nqa, alpha)
            g[k, col] = (
                lp[_LN_KQ]
                + lp[_NRHO] * math.log(rho)
                + lp[_NV] * math.log(vk * vs)
                + math.log(qa)
                - lp[_LN_HEAT_MAX]
            )
            g_r[k, col] = lp[_NRHO] * rho_r / rho
            g_v[k, col] = lp[_NV] / vk + qa_a * alpha_v / qa
            col += 1
        if lp[_QBAR] == 1.0:
            vd = vk * vs
            g[k, col] = math.log(0.5 * rho * vd * vd) - lp[_LN_QBAR_MAX]
            g_r[k, col] = rho_r / rho
            g_v[k, col] = 2.0 / vk
            col += 1
        if lp[_LOAD] == 1.0:
            qk = kb * rho * vk * vk
            qk_r = kb * rho_r * vk * vk
            qk_v = 2.0 * kb * rho * vk
            lift, drag = qk * cl, qk * cd
            n2 = lift * lift + drag * drag
            lift_v = qk_v * cl + qk * dcl * alpha_v
            drag_v = qk_v * cd + qk * dcd * alpha_v
            g[k, col] = 0.5 * math.log(n2) - lp[_LN_LOAD_MAX]
            g_r[k, col] = (lift * qk_r * cl + drag * qk_r * cd) / n2
            g_v[k, col] = (lift * lift_v + drag * drag_v) / n2
    return g, g_r, g_v


@njit(cache=True, nogil=True, error_model="numpy")
def smooth_max_kernel(
    g: Array, states: Array, partials: Array, aug: Array, width: Array
) -> tuple[Array, Array, Array]:
    """The smooth maximum over each interval's J samples of every constraint and its gradient
    carried through the samples' maps (``between_nodes.smooth_max_rows``).

    ``g`` (N, J, m); ``partials`` (P, N, J, m): the constraints' partials in the states
    ``states`` (P,); ``aug`` (N, J, 7, 11): [x | Phi | B- | B+ | S] of every sample
    (``IntervalSamples.augmented``). Returns the rows' values (N, m), their coefficients
    (N, m, 10) and the worst samples (N, m).
    """
    n_int, n_smp, m = g.shape
    ncol = aug.shape[3] - 1
    value = np.empty((n_int, m))
    coef = np.zeros((n_int, m, ncol))
    worst = np.empty((n_int, m))
    e = np.empty(n_smp)
    for n in range(n_int):
        for c in range(m):
            top = g[n, 0, c]
            for j in range(1, n_smp):
                top = max(top, g[n, j, c])
            total = 0.0
            for j in range(n_smp):
                e[j] = math.exp((g[n, j, c] - top) / width[c])
                total += e[j]
            worst[n, c] = top
            value[n, c] = top + width[c] * math.log(total)
            for j in range(n_smp):
                wj = e[j] / total
                for q in range(states.size):
                    wp = wj * partials[q, n, j, c]
                    i = states[q]
                    for col in range(ncol):
                        coef[n, c, col] += wp * aug[n, j, i, col + 1]
    return value, coef, worst


def warm_up(forces: Array) -> None:
    """Compile (or load from the cache) both kernels on a one-point case with every limit and a
    three-term alpha factor; ``forces``: ``models.bank_state_compiled.compiled_parameters``'
    layout. Called by ``worker.solver.warmup.warm_up``."""
    limits = np.zeros(_QA + 3)
    limits[[_HEAT, _QBAR, _LOAD, _NQA, _QA]] = [1.0, 1.0, 1.0, 3.0, 1.0]
    point = np.array([1.015])
    g, g_r, _ = log_rows_kernel(point, np.array([0.9]), limits, forces)
    aug = np.zeros((1, 1, N, AUGMENTED_COLUMNS))
    smooth_max_kernel(g[None], np.array([0, 3]), np.stack([g_r[None]] * 2), aug, np.ones(3))
