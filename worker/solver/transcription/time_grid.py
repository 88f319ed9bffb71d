"""Uniform time grid and the initial reference of the time-domain SCP (paper 002 sec. 4).

The initial reference is the propagation of the nonlinear dynamics under a constant bank (the
paper's "given initial control") on a uniform grid. When no bank is given, a sweep of constant
banks is propagated at once (vectorized over candidates) and the one ending closest to the
terminal conditions, without reaching the ground, is kept. With a free final time the sweep is
flown on a fine grid until it first reaches the terminal altitude (or speed): each bank's
crossing time is its flight time, and the kept bank's crossing time is the reference's final
time, so that no final time has to be guessed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from worker.solver.models.bank_state import bank_state_dynamics
from worker.solver.models.bank_state_compiled import chain_kernel, compiled_parameters, float_arrays
from worker.solver.problem import EntryProblem
from worker.solver.trajectory import TIME_STATE_NAMES

Array = np.ndarray

GUESS_SUBSTEPS = 2  # RK4 steps per interval: the guess only has to be a sensible reference
SWEEP_DEG = np.arange(-60.0, 61.0, 10.0)
# miss units of the sweep's score: 5 km, 5 deg, 500 m/s, 5 deg, 5 deg
MISS_UNIT = np.array([5e3, 5.0, 5.0, 500.0, 5.0, 5.0])
FREE_STEP_S = 5.0  # interval of the free-final-time sweep's fine grid (two RK4 steps each)
FREE_HORIZON_S = 6000.0  # longest flight the sweep looks at when the final time is unbounded


class InitialGuessError(ValueError):
    """No constant-bank propagation of the requested kind stays above the ground."""


@dataclass
class Reference:
    """Nodes (K, 7), bank rates (K,) and interval lengths (N,), nondimensional."""

    z: Array
    w: Array
    s: Array
    bank_deg: float


def uniform_intervals(final_time: float, nodes: int) -> Array:
    """N = nodes - 1 equal interval lengths summing to ``final_time``."""
    return np.full(nodes - 1, final_time / (nodes - 1))


def propagate_constant_bank(
    problem: EntryProblem, banks: Array, s: Array, *, compiled: bool = True
) -> Array:
    """Nodes (C, K, 7) of propagations under each constant bank in ``banks`` (rad), batched;
    the compiled kernel when the force models have one (``compiled=False``: numpy)."""
    c = banks.size
    x = np.tile(np.r_[problem.y0, 0.0], (c, 1))
    x[:, -1] = banks
    params = compiled_parameters(problem.forces, problem.omega) if compiled else None
    if params is not None:  # the same RK4 steps, compiled (models.bank_state_compiled)
        xa, sa = float_arrays(x, s)
        chain: Array = chain_kernel(xa, sa, params, GUESS_SUBSTEPS)
        return chain
    z = np.empty((c, s.size + 1, x.shape[1]))
    z[:, 0] = x
    zero = np.zeros(c)
    with np.errstate(all="ignore"):
        for k, sk in enumerate(s):
            h = sk / GUESS_SUBSTEPS
            for _ in range(GUESS_SUBSTEPS):
                k1 = _rate(problem, x, zero)
                k2 = _rate(problem, x + 0.5 * h * k1, zero)
                k3 = _rate(problem, x + 0.5 * h * k2, zero)
                k4 = _rate(problem, x + h * k3, zero)
                x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
                x[x[:, 0] < 1.0] = np.nan  # below ground: this candidate is out
            z[:, k + 1] = x
    return z


def _rate(problem: EntryProblem, x: Array, w: Array) -> Array:
    return bank_state_dynamics(x, w, problem.forces, problem.omega, jacobians=False).F


def _miss(problem: EntryProblem, end: Array) -> Array:
    """Scaled distance of end states (C, 7) to the terminal targets; inf when not finite."""
    sc = problem.scales
    si = np.column_stack(
        [
            (end[:, 0] - 1.0) * sc.radius_m,
            np.degrees(end[:, 1]),
            np.degrees(end[:, 2]),
            end[:, 3] * sc.speed_m_s,
            np.degrees(end[:, 4]),
            np.degrees(end[:, 5]),
        ]
    )
    score = np.zeros(end.shape[0])
    for j, name in enumerate(TIME_STATE_NAMES):
        target = problem.terminal[name].target()
        if target is None:
            continue
        value = (target - 1.0) * sc.radius_m if j == 0 else target
        if j == 3:
            value = target * sc.speed_m_s
        elif j > 0:
            value = math.degrees(target)
        score += ((si[:, j] - value) / MISS_UNIT[j]) ** 2
    return np.where(np.isfinite(score), score, np.inf)


def _sweep(problem: EntryProblem, candidates: Array, s: Array) -> tuple[Array, Array]:
    """Nodes (C, K, 7) of the constant-bank propagations of ``candidates`` (deg) on intervals
    ``s`` and each end's miss of the terminal targets (inf when it reached the ground)."""
    z = propagate_constant_bank(problem, np.radians(candidates), s)
    return z, _miss(problem, z[:, -1])


def _sweep_candidates(problem: EntryProblem) -> Array:
    """The sweep's constant banks within the bank range, deg; a range too narrow to hold three
    of them is swept at its ends and middle as well."""
    low, high = math.degrees(problem.bank_min), math.degrees(problem.bank_max)
    sweep = SWEEP_DEG
    candidates: Array = sweep[(sweep >= low) & (sweep <= high)]
    if candidates.size < 3:
        candidates = np.unique(np.r_[candidates, low, 0.5 * (low + high), high])
    return candidates


def sign_start_banks(problem: EntryProblem, nodes: int) -> list[float]:
    """The constant banks (deg) of a two-start run: the sweep's closest to the terminal
    conditions, then the closest of the other sign; one entry when the other sign has no
    propagation that stays above the ground (or the closest bank is zero). The caller decides
    whether the bank is free (no given or fixed initial bank).

    The bank's sign in the thin early arc, where it turns the path but barely the energy,
    selects between local optima of the same problem (paper 002 case 1 at 120 nodes: 969.8 m/s
    from +20 deg, 970.8 m/s from -10 deg); one start per sign lets the better one be kept.
    """
    candidates = _sweep_candidates(problem)
    if problem.final_time is None:
        score, _ = free_sweep(problem, candidates)
    else:
        _, score = _sweep(problem, candidates, uniform_intervals(problem.final_time, nodes))
    best = int(np.argmin(score))
    if not np.isfinite(score[best]) or candidates[best] == 0.0:
        return [float(candidates[best])]
    other = np.where(np.sign(candidates) == -np.sign(candidates[best]), score, np.inf)
    second = int(np.argmin(other))
    if not np.isfinite(other[second]):
        return [float(candidates[best])]
    return [float(candidates[best]), float(candidates[second])]


def initial_reference(
    problem: EntryProblem, nodes: int, initial_bank_deg: float | None
) -> Reference:
    """The propagated constant-bank reference on a uniform grid (paper 002 sec. 4); with a free
    final time, over the flight time of the kept bank (``free_sweep``)."""
    fixed_bank = problem.initial_bank_deg
    if initial_bank_deg is not None:
        candidates = np.array([initial_bank_deg])
    elif fixed_bank is not None:
        candidates = np.array([fixed_bank])
    else:
        candidates = _sweep_candidates(problem)
    if problem.final_time is None:
        free_score, times = free_sweep(problem, candidates)
        best = int(np.argmin(free_score))
        if not np.isfinite(free_score[best]):
            raise InitialGuessError(
                "no constant-bank flight of the sweep reaches the terminal altitude (or speed) "
                "above the ground within the time looked at; give method.initial_bank_deg, an "
                "initial_guess, or final_time.max_s"
            )
        candidates = candidates[best : best + 1]
        s = uniform_intervals(float(times[best]), nodes)
    else:
        s = uniform_intervals(problem.final_time, nodes)
    z, score = _sweep(problem, candidates, s)
    best = int(np.argmin(score))
    if not np.isfinite(score[best]):
        if candidates.size == 1:
            raise InitialGuessError(
                f"the propagation under a constant bank of {candidates[0]:g} deg reaches the "
                "ground before the final time; choose another method.initial_bank_deg"
            )
        raise InitialGuessError(
            "no constant-bank propagation of the sweep stays above the ground for the whole "
            "flight time; give method.initial_bank_deg"
        )
    return Reference(z=z[best], w=np.zeros(nodes), s=s, bank_deg=float(candidates[best]))


def guess_reference(problem: EntryProblem, nodes: int) -> Reference:
    """The caller's initial guess (``problem.guess``) on a uniform grid: its states and bank
    interpolated in time scaled to the final time, the given initial state and bank at the
    first node, the bank within its range and its rate the guess's slope (within its bound)."""
    assert problem.guess is not None
    final_time = problem.final_time  # a free final time: the guess's own duration
    s = uniform_intervals(float(problem.guess.t[-1]) if final_time is None else final_time, nodes)
    t = np.concatenate([[0.0], np.cumsum(s)])
    y, bank = problem.guess.on_times(t)
    y[0] = problem.y0
    if problem.initial_bank is not None:
        bank[0] = problem.initial_bank
    bank = np.clip(bank, problem.bank_min, problem.bank_max)
    w = np.gradient(bank, t)
    if problem.bank_rate_max is not None:
        w = np.clip(w, -problem.bank_rate_max, problem.bank_rate_max)
    return Reference(z=np.column_stack([y, bank]), w=w, s=s, bank_deg=math.degrees(bank[0]))


def _end_condition(problem: EntryProblem) -> tuple[int, float]:
    """The state (0: radius, 3: speed) whose terminal target ends a free-time flight, and that
    target (nondimensional); the altitude's when it has one."""
    for j, name in ((0, "altitude_m"), (3, "velocity_m_s")):
        target = problem.terminal[name].target()
        if target is not None:
            return j, target
    raise InitialGuessError(
        "a free final time needs a terminal altitude or speed to end the flight; give "
        "terminal.altitude_m"
    )


def free_sweep(problem: EntryProblem, candidates: Array) -> tuple[Array, Array]:
    """Each constant bank's (deg) miss of the terminal targets where its flight first falls to
    the terminal altitude (or speed), and the time it does (nondimensional; inf and nan when it
    never does above the ground within ``final_time_max`` or the sweep's horizon)."""
    sc = problem.scales
    horizon = (
        problem.final_time_max if problem.final_time_max is not None else FREE_HORIZON_S / sc.time_s
    )
    steps = max(math.ceil(horizon * sc.time_s / FREE_STEP_S), 1)
    s = uniform_intervals(horizon, steps + 1)
    z = propagate_constant_bank(problem, np.radians(candidates), s)
    j, target = _end_condition(problem)
    t = np.concatenate([[0.0], np.cumsum(s)])
    score = np.full(candidates.size, np.inf)
    times = np.full(candidates.size, np.nan)
    for c in range(candidates.size):
        path = z[c, :, j]
        below = np.flatnonzero(~(path > target))  # also a non-finite (grounded) node
        if below.size == 0 or below[0] == 0 or not np.isfinite(path[below[0]]):
            continue
        k = int(below[0])
        frac = (path[k - 1] - target) / (path[k - 1] - path[k])
        end = z[c, k - 1] + frac * (z[c, k] - z[c, k - 1])
        score[c] = _miss(problem, end[None, :])[0]
        times[c] = t[k - 1] + frac * (t[k] - t[k - 1])
    return score, times


FALLBACK_SPAN_S = 1600.0
"""Flight time that scales the grid bounds of a free final time whose start failed (paper
002's; the method then stops at once with the start's reason)."""


def free_time_span(problem: EntryProblem, first: Reference | InitialGuessError) -> float:
    """The flight time (nondimensional) a free final time's grid bounds scale with: that of the
    initial reference."""
    if isinstance(first, InitialGuessError):
        return FALLBACK_SPAN_S / problem.scales.time_s
    return float(np.sum(first.s))
