"""A global search for a start (paper 004 sec. 2.2-2.4): each phase flown with a few control
parameters, scored by its propagated end-condition misses, and searched by GA or PSO.

Each phase is flown with its angle of attack and bank linear between ``knots`` evenly spaced
knots, for a duration, and, where it may thrust, at full thrust during one burn (start and length
as shares of the phase). A candidate is scored as paper 004's heuristic objectives do: its
propagated end-condition misses in each phase (sec. 2.4.1 at the bottom point, 2.4.2 at the
exit), in tolerance units, with path-limit excess, plus a small share of the objective when the
caller prices one. The population is propagated together by a fixed-step RK4 (``STEPS`` per
phase), one numpy call per stage for all candidates. The phases are searched one after the
other (``search_phases``); the best candidate is handed to a method as its mesh's values
(``lgl-sqp``) or, for a one-phase flight, as a start trajectory (``start_path``) that any
method interpolates as it does a user's guess.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from worker.solver.global_search import SearchBudget, SearchOutcome, global_search
from worker.solver.guess_path import GuessPath
from worker.solver.models.powered import path_ratios
from worker.solver.phased_problem import PhasedProblem
from worker.solver.trajectory import TIME_STATE_NAMES

Array = np.ndarray

STEPS = 120
"""RK4 steps per phase while searching (about 12 s of a 1 500 s descent)."""
FINE_STEPS = 1000
"""RK4 steps per phase of the chosen candidate's trajectory."""
MISS_UNITS = (1000.0, 1.0, 1.0, 100.0, 1.0, 1.0)
"""What one unit of score is per state at a phase end: 1 km, 1 deg, 1 deg, 100 m/s, 1 deg, 1 deg."""
PATH_WEIGHT = 10.0
OBJECTIVE_SHARE = 0.5
SPEED_SHARE = 0.02
"""Score per 100 m/s of a phase's end speed taken off when the propellant is minimized and a
powered phase may follow (paper 004's descent heuristic: maximize the bottom speed)."""
OBJECTIVE_CAP = 100.0
"""Largest magnitude of the objective's share in a score: the end misses decide."""
FAILED_SCORE = 1.0e9
DEFAULT_ALPHA_DEG = 20.0


@dataclass
class Parameterization:
    """Where each phase's parameters sit in a candidate vector, and their bounds."""

    problem: PhasedProblem
    knots: int

    def __post_init__(self) -> None:
        lo: list[float] = []
        hi: list[float] = []
        self.offsets: list[int] = []
        base = self.problem.base
        self.scheduled = base.forces.alpha_schedule is not None and not base.alpha_optimized
        """The angle of attack follows the vehicle's schedule of speed (not searched)."""
        for ph in self.problem.phases:
            self.offsets.append(len(lo))
            k = self.knots
            alpha_lo, alpha_hi = (0.0, 0.0) if self.scheduled else ph.alpha_range
            lo += [alpha_lo] * k + [ph.bank_range[0]] * k + [ph.duration_min]
            hi += [alpha_hi] * k + [ph.bank_range[1]] * k + [ph.duration_max]
            if ph.thrust_max > 0:
                lo += [0.0, 0.0]
                hi += [1.0, 1.0]
        self.lower, self.upper = np.array(lo), np.array(hi)

    def controls(self, params: Array, p: int, s: float | Array) -> Array:
        """(P, n_controls) controls of phase ``p`` at normalized time ``s`` for candidates
        ``params`` (P, n)."""
        ph = self.problem.phases[p]
        o, k = self.offsets[p], self.knots
        if k == 1:
            alpha, bank = params[:, o], params[:, o + 1]
        else:
            pos = np.clip(np.asarray(s) * (k - 1), 0.0, k - 1 - 1e-12)
            i = np.floor(pos).astype(int)
            w = pos - i
            rows = np.arange(params.shape[0])
            a = params[:, o : o + k]
            b = params[:, o + k : o + 2 * k]
            ii = np.broadcast_to(i, (params.shape[0],))
            ww = np.broadcast_to(w, (params.shape[0],))
            alpha = a[rows, ii] * (1 - ww) + a[rows, ii + 1] * ww
            bank = b[rows, ii] * (1 - ww) + b[rows, ii + 1] * ww
        cols = [alpha, bank]
        if self.problem.model.n_controls == 3:
            if ph.thrust_max > 0:
                start, length = params[:, o + 2 * k + 1], params[:, o + 2 * k + 2]
                on = (s >= start) & (s <= start + length)
                cols.append(np.where(on, ph.thrust_max, 0.0))
            else:
                cols.append(np.zeros(params.shape[0]))
        return np.stack(cols, axis=1)

    def controls_at(self, params: Array, p: int, s: float | Array, x: Array) -> Array:
        """:meth:`controls` with a scheduled angle of attack taken at the states ``x``."""
        u = self.controls(params, p, s)
        if self.scheduled:
            forces = self.problem.base.forces
            with np.errstate(all="ignore"):
                alpha_deg, _ = forces.alpha(np.abs(x[:, 3]))
            u[:, 0] = np.radians(alpha_deg)
        return u

    def phase_slice(self, p: int) -> slice:
        """Phase ``p``'s parameters in a candidate vector."""
        end = self.offsets[p + 1] if p + 1 < len(self.offsets) else self.lower.size
        return slice(self.offsets[p], end)

    def duration(self, params: Array, p: int) -> Array:
        return params[:, self.offsets[p] + 2 * self.knots]


def fly(
    par: Parameterization,
    params: Array,
    steps: int,
    phases: range | None = None,
    start: Array | None = None,
) -> list[tuple[Array, Array, Array]]:
    """Propagate candidates through ``phases`` (default all) from ``start`` (default the
    initial state): per phase (s (steps+1,), states (steps+1, P, nx), controls (steps+1, P,
    nu)) by RK4 in normalized time."""
    model = par.problem.model
    P = params.shape[0]
    x0 = par.problem.x0 if start is None else start
    x = np.repeat(np.asarray(x0, dtype=float)[None, :], P, axis=0)
    out = []
    for p in phases if phases is not None else range(len(par.problem.phases)):
        tau = par.duration(params, p)[:, None]
        s_grid = np.linspace(0.0, 1.0, steps + 1)
        h = 1.0 / steps
        xs, us = [x], [par.controls_at(params, p, 0.0, x)]

        def rate(xx: Array, s: float, p: int = p, tau: Array = tau) -> Array:
            with np.errstate(all="ignore"):
                return tau * model.rates(xx, par.controls_at(params, p, s, xx))

        for i in range(steps):
            s = s_grid[i]
            k1 = rate(x, s)
            k2 = rate(x + 0.5 * h * k1, s + 0.5 * h)
            k3 = rate(x + 0.5 * h * k2, s + 0.5 * h)
            k4 = rate(x + h * k3, s + h)
            x = x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
            x[:, 0] = np.maximum(x[:, 0], 1.0 - 1e-3)  # keep a crashed candidate computable
            if x.shape[1] > 6:
                x[:, 6] = np.maximum(x[:, 6], 1e-3)
            xs.append(x)
            us.append(par.controls_at(params, p, s + h, x))
        out.append((s_grid, np.array(xs), np.array(us)))
    return out


ObjectiveOf = Callable[[Array, Array], Array]
"""The normalized objective of candidates from their final states (P, n_states) and phase
durations (P, n_phases)."""


def score(
    par: Parameterization,
    params: Array,
    phases: range | None = None,
    start: Array | None = None,
    objective: ObjectiveOf | None = None,
) -> Array:
    """Paper 004's heuristic score of each candidate over ``phases`` (default all) flown from
    ``start``: end misses in tolerance units, path excess, and, when the last phase is flown and
    an ``objective`` is given, a share of it; a failed propagation scores FAILED_SCORE."""
    pb = par.problem
    sc = pb.base.scales
    flown = phases if phases is not None else range(len(pb.phases))
    flights = fly(par, params, STEPS, flown, start)
    total = np.zeros(params.shape[0])
    propellant = any(t.name == "min_propellant" for t in pb.base.objective)
    to_si = (sc.radius_m, math.degrees(1), math.degrees(1), sc.speed_m_s, math.degrees(1),
             math.degrees(1))  # fmt: skip
    for p, (_, xs, us) in zip(flown, flights, strict=True):
        ph = pb.phases[p]
        end = xs[-1]
        for i, name in enumerate(TIME_STATE_NAMES):
            t = ph.end[name]
            v = end[:, i]
            if t.kind in ("fixed", "soft"):
                assert t.value is not None
                miss = np.abs(v - t.value)
            elif t.kind == "range":
                assert t.lo is not None and t.hi is not None
                miss = np.maximum(np.maximum(t.lo - v, v - t.hi), 0.0)
            else:
                continue
            total += miss * to_si[i] / MISS_UNITS[i]
        flat_x = xs.reshape(-1, xs.shape[-1])
        flat_u = us.reshape(-1, us.shape[-1])
        with np.errstate(all="ignore"):
            ratios = path_ratios(pb.model, ph.limits, flat_x, flat_u)
        if ratios.shape[1]:
            excess = np.maximum(ratios.reshape(xs.shape[0], xs.shape[1], -1) - 1.0, 0.0)
            total += PATH_WEIGHT * excess.max(axis=(0, 2))
        ground = (xs[:, :, 0] < 1.0).any(axis=0)
        total += np.where(ground, 100.0, 0.0)
        if p < len(pb.phases) - 1 and propellant:
            # paper 004 sec. 2.4.1: the faster the bottom point, the less thrust the exit needs
            total -= SPEED_SHARE * end[:, 3] * sc.speed_m_s / MISS_UNITS[3]
    if objective is not None and flown[-1] == len(pb.phases) - 1:
        durations = np.column_stack([par.duration(params, p) for p in range(len(pb.phases))])
        with np.errstate(all="ignore"):
            share = OBJECTIVE_SHARE * objective(flights[-1][1][-1], durations)
        total += np.clip(share, -OBJECTIVE_CAP, OBJECTIVE_CAP)
    wild = np.zeros(params.shape[0], dtype=bool)
    for _, xs, _ in flights:  # a candidate that left the physical envelope failed
        wild |= ~np.isfinite(xs).all(axis=(0, 2)) | (np.abs(xs[:, :, 3]) > 3.0).any(axis=0)
        wild |= (xs[:, :, 0] > 1.5).any(axis=0)
    return np.where(np.isfinite(total) & ~wild, total, FAILED_SCORE)


def constant_params(par: Parameterization) -> Array:
    """Constant mid-range controls (alpha 20 deg where allowed, wings level where allowed), the
    middle of each duration range, no burn."""
    v = 0.5 * (par.lower + par.upper)
    for p, ph in enumerate(par.problem.phases):
        o, k = par.offsets[p], par.knots
        v[o : o + k] = np.clip(math.radians(DEFAULT_ALPHA_DEG), *ph.alpha_range)
        v[o + k : o + 2 * k] = np.clip(0.0, *ph.bank_range)
        if ph.thrust_max > 0:
            v[o + 2 * k + 1 : o + 2 * k + 3] = 0.0
    return v


def search_phases(
    par: Parameterization,
    *,
    algorithm: str,
    seed: int,
    population: int,
    budget: SearchBudget,
    objective: ObjectiveOf | None = None,
    progress: Callable[[int, float], None] | None = None,
) -> SearchOutcome:
    """The best candidate of a GA or PSO search, phase after phase as paper 004 separates its
    descent and exit searches (sec. 2.4): each phase's parameters are searched from the end
    state of the phases before, with an equal share of the budget; the first searched
    generation of a later phase is numbered on from the previous phase's. The outcome's ``x``
    is the whole candidate, its ``score`` that of the whole flight."""
    n_phases = len(par.problem.phases)
    share = SearchBudget(
        max(budget.max_evaluations // n_phases, population),
        budget.time_limit_s / n_phases if budget.time_limit_s is not None else None,
    )
    best = constant_params(par)
    start = np.asarray(par.problem.x0, dtype=float)
    outcomes: list[SearchOutcome] = []
    generations = 0
    for p in range(n_phases):
        sl = par.phase_slice(p)

        # a parameter whose bounds meet (a fixed duration, a scheduled alpha) is not searched
        free = np.flatnonzero(par.upper[sl] > par.lower[sl]) + sl.start

        def phase_score(cand: Array, p: int = p, free: Array = free, start: Array = start) -> Array:
            full = np.repeat(best[None, :], cand.shape[0], axis=0)
            full[:, free] = cand
            return score(par, full, range(p, p + 1), start, objective)

        def phase_progress(generation: int, value: float, offset: int = generations) -> None:
            if progress is not None:
                progress(offset + generation, value)

        outcome = global_search(
            phase_score,
            par.lower[free],
            par.upper[free],
            algorithm=algorithm,  # type: ignore[arg-type]
            seed=seed + p,
            population=population,
            budget=share,
            progress=phase_progress,
        )
        outcomes.append(outcome)
        generations += outcome.generations
        best[free] = outcome.x
        flown = fly(par, best[None, :], FINE_STEPS, range(p, p + 1), start)
        start = flown[0][1][-1, 0]
    return SearchOutcome(
        x=best,
        score=float(score(par, best[None, :], objective=objective)[0]),
        evaluations=sum(o.evaluations for o in outcomes),
        generations=generations,
        best_by_generation=[v for o in outcomes for v in o.best_by_generation],
        wall_s=sum(o.wall_s for o in outcomes),
        algorithm=outcomes[0].algorithm,
        seed=seed,
        population=population,
        stopped_by=outcomes[-1].stopped_by,
    )


def start_path(par: Parameterization, params: Array) -> GuessPath:
    """A one-phase flight's candidate flown finely, as a start trajectory (the six point-mass
    states, bank and angle of attack; nondimensional, time from 0)."""
    if len(par.problem.phases) != 1:
        raise ValueError("a start trajectory is made for a one-phase flight")
    s_grid, xs, us = fly(par, params[None, :], FINE_STEPS)[0]
    t = s_grid * float(par.duration(params[None, :], 0)[0])
    alpha = None if par.scheduled else us[:, 0, 0]
    return GuessPath(t=t, y=xs[:, 0, :6], bank=us[:, 0, 1], alpha=alpha)
