"""``energy_defect.exact_increments`` compiled (numba) for the compiled force models.

The deferred correction integrates every interval by RK4 on each iteration once it is on; in
numpy that is 33 evaluations of the vectorized energy-form rates per iteration (about 7 ms at
121 nodes, a third of the iteration), compiled a loop over intervals and substeps (well under a
millisecond). Same equations (``models.eom``, time form divided by de/dt = -r'/r^2 - V V'), the
same forces (``bank_state_compiled.aero_terms``), the same heat rate (paper 000 eq. 12 with the
alpha factor, as ``path_limits.path_values``) and the same control between the nodes (bank
angle and magnitude linear in energy, ``energy_defect.interval_control``);
``tests/unit/test_energy_defect.py`` holds both forms equal.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from worker.solver.models.bank_state_compiled import _VS, float_arrays
from worker.solver.models.flown_rates import point_time_rates
from worker.solver.polynomial import horner
from worker.solver.problem import EntryProblem
from worker.solver.transcription.energy_defect import IntervalIncrements

Array = np.ndarray

HEAT, TIME = 0, 1
"""Running-cost kinds: heat load (J/m^2 per unit energy) and flight time (s per unit energy)."""

# Layout of the running-cost parameters: time scale, ln k_q, speed and density exponents, the
# number of coefficients of the alpha factor, then the coefficients (lowest order first)
_T_SCALE, _LN_KQ, _NV, _NRHO, _NQA = range(5)
_QA = 5
_NX = 5  # energy-form states r, theta, phi, gamma, psi


def running_parameters(problem: EntryProblem) -> Array:
    """The running costs' parameters for the kernel (heat terms zero without a heat model)."""
    heat = problem.heat_model
    head = np.zeros(_QA)
    head[_T_SCALE] = problem.scales.time_s
    poly: tuple[float, ...] = ()
    if heat is not None:
        poly = tuple(heat.alpha_polynomial or ())
        head[[_LN_KQ, _NV, _NRHO, _NQA]] = [
            math.log(heat.k_q),
            heat.velocity_exponent,
            heat.density_exponent,
            len(poly),
        ]
    return np.concatenate([head, np.asarray(poly, dtype=float)])


@njit(cache=True, nogil=True, error_model="numpy")
def _stage(
    state: Array, e: float, u1: float, u2: float, p: Array, rp: Array, kinds: Array, out: Array
) -> None:
    """d(state)/de into ``out``: the energy-form rates, then each running cost's density."""
    r, ph, ga, ps = state[0], state[2], state[3], state[4]
    v = math.sqrt(2.0 * (1.0 / r - e))
    f, rho, alpha = point_time_rates(r, ph, v, ga, ps, u1, u2, p)
    edot = -f[0] / (r * r) - v * f[3]
    inv = 1.0 / edot
    out[0], out[1], out[2] = f[0] * inv, f[1] * inv, f[2] * inv
    out[3], out[4] = f[4] * inv, f[5] * inv
    for j in range(kinds.size):
        if kinds[j] == TIME:
            out[_NX + j] = rp[_T_SCALE] * inv
        else:
            qa = 1.0
            nqa = int(rp[_NQA])
            if nqa > 0:
                qa = horner(rp, _QA, nqa, alpha)[0]
            ln_q = rp[_LN_KQ] + rp[_NRHO] * math.log(rho) + rp[_NV] * math.log(v * p[_VS])
            out[_NX + j] = rp[_T_SCALE] * math.exp(ln_q) * qa * inv


@njit(cache=True, nogil=True, error_model="numpy")
def _control(b0: float, b1: float, s0: float, s1: float, tau: float) -> tuple[float, float]:
    """The control at ``tau`` of an interval: bank and magnitude linear between the nodes."""
    bank = b0 + tau * (b1 - b0)
    size = s0 + tau * (s1 - s0)
    return size * math.cos(bank), size * math.sin(bank)


@njit(cache=True, nogil=True, error_model="numpy")
def increments_kernel(
    e: Array, x: Array, u: Array, p: Array, rp: Array, kinds: Array, substeps: int
) -> Array:
    """(N, 5 + m): each interval's state increment, then its running-cost integrals."""
    n = e.size - 1
    width = _NX + kinds.size
    result = np.empty((n, width))
    state = np.empty(width)
    trial = np.empty(width)
    k1, k2, k3, k4 = np.empty(width), np.empty(width), np.empty(width), np.empty(width)
    step = 1.0 / substeps
    for i in range(n):
        h = e[i + 1] - e[i]
        b0 = math.atan2(u[i, 1], u[i, 0])
        b1 = math.atan2(u[i + 1, 1], u[i + 1, 0])
        s0 = math.hypot(u[i, 0], u[i, 1])
        s1 = math.hypot(u[i + 1, 0], u[i + 1, 1])
        state[:_NX] = x[i]
        state[_NX:] = 0.0
        for sub in range(substeps):
            tau = sub * step
            half = tau + 0.5 * step
            c1, c2 = _control(b0, b1, s0, s1, tau)
            _stage(state, e[i] + tau * h, c1, c2, p, rp, kinds, k1)
            trial[:] = state + (0.5 * step * h) * k1
            c1, c2 = _control(b0, b1, s0, s1, half)
            _stage(trial, e[i] + half * h, c1, c2, p, rp, kinds, k2)
            trial[:] = state + (0.5 * step * h) * k2
            _stage(trial, e[i] + half * h, c1, c2, p, rp, kinds, k3)
            trial[:] = state + (step * h) * k3
            c1, c2 = _control(b0, b1, s0, s1, tau + step)
            _stage(trial, e[i] + (tau + step) * h, c1, c2, p, rp, kinds, k4)
            state += (step * h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        result[i, :_NX] = state[:_NX] - x[i]
        result[i, _NX:] = state[_NX:]
    return result


def compiled_increments(
    problem: EntryProblem,
    params: Array,
    e: Array,
    x: Array,
    u: Array,
    running: list[str],
    substeps: int,
) -> IntervalIncrements:
    """``energy_defect.exact_increments`` for the running costs ``running`` (names), compiled."""
    kinds = np.array([HEAT if name == "min_heat_load" else TIME for name in running], np.int64)
    ee, xx, uu = float_arrays(e, x, u)
    out = increments_kernel(ee, xx, uu, params, running_parameters(problem), kinds, substeps)
    return IntervalIncrements(state=out[:, :_NX], running=out[:, _NX:])


def warm_up(p: Array) -> None:
    """Compile (or load) the kernel on a tiny case."""
    e = np.array([-0.95, -0.9])
    x = np.array([[1.015, 0.0, 0.0, 0.0, 0.0], [1.012, 0.01, 0.0, -0.01, 0.0]])
    u = np.array([[1.0, 0.0], [0.9, 0.1]])
    rp = np.zeros(_QA)
    rp[_T_SCALE] = 800.0
    increments_kernel(e, x, u, p, rp, np.array([HEAT, TIME], np.int64), 1)
