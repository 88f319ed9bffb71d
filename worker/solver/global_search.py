"""A seeded, budgeted global search over a box of control parameters, by pymoo's genetic
algorithm or particle swarm: the global initial guess of paper 004's method, which a local
trajectory optimization then refines.

The search is a kept library (pymoo), not ours; this module fixes how it is driven: one call of
the scorer per generation (a vectorized scorer stays vectorized), a budget in candidate
evaluations and wall seconds checked between generations, failed candidates (nan) ranked worst,
a private random generator per run, and the best candidate ever scored as the answer.

pymoo is imported inside :func:`global_search`, not here: its import costs more than the rest of
this module (some 60 ms on top of the solver core), and the service imports the solver core at
start-up whether or not a run searches.
"""

from __future__ import annotations

import copy
import random
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal, get_args

import numpy as np
import numpy.typing as npt

from worker.solver.solve_clock import SolveClock

FloatArray = npt.NDArray[np.float64]

Algorithm = Literal["ga", "pso"]
"""The search: ``"ga"`` pymoo's real-coded genetic algorithm, ``"pso"`` its particle swarm."""

StopReason = Literal["evaluations", "time", "converged"]
"""What ended a search: the evaluation budget, the time limit, or pymoo's convergence test."""

Scorer = Callable[[FloatArray], npt.ArrayLike]
"""Scores a population: candidates (P, n) inside the box -> scores (P,), lower is better. A
failed candidate may score inf or nan (nan, and -inf, count as inf: worst)."""

_CONVERGENCE_PERIOD = 30
"""Generations over which pymoo's default single-objective convergence test looks back."""


@dataclass(frozen=True)
class SearchBudget:
    """How much a search may spend: candidate evaluations and, optionally, CPU seconds of the
    process (``solve_clock``, with its wall-clock safety; both checked between generations, so
    the last generation runs to its end)."""

    max_evaluations: int = 4000
    """Stop once this many candidates have been scored (> 0); the last generation may pass it
    by less than one population."""
    time_limit_s: float | None = None
    """Stop at the end of the first generation that ends with this many CPU seconds spent since
    the start (> 0), or ``WALL_FACTOR`` times as many wall seconds; None: no limit."""

    def __post_init__(self) -> None:
        """Reject a budget that cannot be spent (a ValueError naming the field)."""
        n = self.max_evaluations
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n <= 0:
            raise ValueError(f"max_evaluations must be a positive integer, got {n!r}")
        t = self.time_limit_s
        if t is not None and not (isinstance(t, int | float) and t > 0):
            raise ValueError(f"time_limit_s must be None or a positive number, got {t!r}")


JOB_SHARE = 0.5
"""Most of a job's time limit a global search for a start may take: the rest is the method's,
so a search asked for more than its job allows still hands the method a start in time."""


def search_seconds(asked_s: float, job_limit_s: float) -> float:
    """The CPU seconds a search asked for ``asked_s`` may take in a job of ``job_limit_s``."""
    return min(asked_s, JOB_SHARE * job_limit_s)


def clamp_note(asked_s: float, job_limit_s: float) -> str:
    """What the clamp of :func:`search_seconds` did, for the provenance ("" when nothing)."""
    allowed = search_seconds(asked_s, job_limit_s)
    if allowed >= asked_s:
        return ""
    return (
        f"; its time limit {asked_s:g} s was cut to {allowed:g} s, {JOB_SHARE:.0%} of the job's "
        f"time limit {job_limit_s:g} s (the rest is the method's)"
    )


@dataclass
class SearchOutcome:
    """The best candidate a search found and how the search went (for the run's record and a
    live history)."""

    x: FloatArray
    """The best candidate scored (n,): the first of the lowest score."""
    score: float
    """Its score (inf when every candidate failed; x is then the first one scored)."""
    evaluations: int
    """Candidates scored (rows passed to the scorer)."""
    generations: int
    """Generations run, the initial population the first."""
    best_by_generation: list[float] = field(repr=False)
    """The best score so far after each generation (non-increasing)."""
    wall_s: float
    """Wall seconds of the search."""
    algorithm: Algorithm
    seed: int
    population: int
    stopped_by: StopReason
    """The budget's evaluations, its time limit, or convergence (pymoo's default test: in each
    of the last 30 generations the best score improved by at most 1e-6, absolute, or the best
    point moved by at most 1e-8 of the box)."""


class _Tally:
    """Scores populations through the caller's scorer and keeps the count and the best seen,
    independent of what pymoo keeps (so the answer is the best ever scored, in either search)."""

    def __init__(self, score: Scorer, lower: FloatArray, upper: FloatArray) -> None:
        self.score = score
        self.lower, self.upper = lower, upper
        self.evaluations = 0
        self.best_x: FloatArray | None = None
        self.best_f = float("inf")

    def __call__(self, X: FloatArray) -> FloatArray:
        """Scores (P,) of candidates X (P, n), failures as inf, the best so far updated."""
        # Clipping is a no-op for pymoo's operators (they keep to the bounds); it makes "inside
        # the box" a guarantee of this module, not of the library.
        candidates = np.clip(np.array(X, dtype=np.float64), self.lower, self.upper)
        f = np.asarray(self.score(candidates), dtype=np.float64)
        if f.shape != (len(candidates),):
            raise ValueError(
                f"score must return one score per candidate, shape ({len(candidates)},), "
                f"got shape {f.shape}"
            )
        f = np.where(np.isfinite(f), f, np.inf)
        self.evaluations += len(candidates)
        if len(f) > 0:
            k = int(np.argmin(f))
            if self.best_x is None or f[k] < self.best_f:
                self.best_x, self.best_f = candidates[k].copy(), float(f[k])
        return f


def _box(lower: npt.ArrayLike, upper: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """The search box as float vectors, or a ValueError naming what is wrong with it."""
    xl = np.asarray(lower, dtype=np.float64)
    xu = np.asarray(upper, dtype=np.float64)
    if xl.ndim != 1 or xl.size == 0:
        raise ValueError(f"lower must be a non-empty vector, got shape {xl.shape}")
    if xu.shape != xl.shape:
        raise ValueError(f"upper must have the shape of lower {xl.shape}, got {xu.shape}")
    if not np.all(np.isfinite(xl)):
        raise ValueError("lower must be finite")
    if not np.all(np.isfinite(xu)):
        raise ValueError("upper must be finite")
    if not np.all(xl < xu):
        bad = np.flatnonzero(~(xl < xu)).tolist()
        raise ValueError(f"lower must be below upper in every component; not at indices {bad}")
    return xl, xu


def _is_int(value: object) -> bool:
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def global_search(
    score: Scorer,
    lower: npt.ArrayLike,
    upper: npt.ArrayLike,
    *,
    algorithm: Algorithm,
    seed: int,
    population: int = 40,
    budget: SearchBudget = SearchBudget(),
    progress: Callable[[int, float], None] | None = None,
) -> SearchOutcome:
    """Minimize ``score`` over the box [lower, upper] by pymoo's GA or PSO, within ``budget``;
    the best candidate scored is the global initial guess of a trajectory optimization.

    ``"ga"`` is pymoo's ``GA`` with its default real-coded operators: random uniform sampling,
    binary tournament selection, simulated binary crossover (SBX, eta 15), polynomial mutation
    (eta 20), elitist survival of the best ``population`` of parents and offspring, duplicates
    eliminated (so a generation may score fewer than ``population`` candidates). ``"pso"`` is
    pymoo's ``PSO`` (adaptive inertia and acceleration, Latin hypercube start) with a swarm of
    ``population`` particles.

    Each generation scores its candidates in one call of ``score``. ``progress(generation,
    best)`` is called after each generation (the first is the initial population) with the best
    score so far; an exception it raises ends the search and propagates. The budget is checked
    after each generation: evaluations first, then the time limit, then convergence.

    Reproducible: the same scorer, box, algorithm, seed, population and budget give the same
    outcome bit for bit, unless the time limit ends the search. The seed goes to pymoo, which
    from 0.6.1.6 on (0.6.2 is pinned) draws from its own ``numpy.random.Generator``; 0.6.1 to
    0.6.1.5 seeded and drew from numpy's and Python's global generators instead, so their states
    are saved and restored around the search: a caller's randomness is untouched either way.
    """
    xl, xu = _box(lower, upper)
    if algorithm not in get_args(Algorithm):
        raise ValueError(f"algorithm must be one of {get_args(Algorithm)}, got {algorithm!r}")
    if not _is_int(seed) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    if not _is_int(population) or population < 2:
        raise ValueError(f"population must be an integer of at least 2, got {population!r}")
    if not isinstance(budget, SearchBudget):
        raise ValueError(f"budget must be a SearchBudget, got {type(budget).__name__}")

    from pymoo.algorithms.soo.nonconvex.ga import GA
    from pymoo.algorithms.soo.nonconvex.pso import PSO
    from pymoo.config import Config
    from pymoo.core.problem import Problem
    from pymoo.termination.default import DefaultSingleObjectiveTermination

    # A missing compiled extension only slows pymoo down; its hint goes to stdout otherwise.
    Config.warnings["not_compiled"] = False

    tally = _Tally(score, xl, xu)

    class _BoxProblem(Problem):  # type: ignore[misc]  # pymoo ships no type hints
        """The box and the scorer as pymoo's vectorized single-objective problem."""

        def __init__(self) -> None:
            super().__init__(n_var=len(xl), n_obj=1, xl=xl, xu=xu, elementwise=False)

        def _evaluate(self, X: FloatArray, out: dict[str, Any], *args: Any, **kwargs: Any) -> None:
            out["F"] = tally(X)[:, None]

    # Copied as pymoo's own minimize() does: the defaults' operator objects are shared.
    search: Any = copy.deepcopy(
        GA(pop_size=population) if algorithm == "ga" else PSO(pop_size=population)
    )
    converged = DefaultSingleObjectiveTermination(
        period=_CONVERGENCE_PERIOD, n_max_gen=None, n_max_evals=None
    )

    start = time.perf_counter()
    clock = SolveClock.start(budget.time_limit_s) if budget.time_limit_s is not None else None
    np_state, py_state = np.random.get_state(), random.getstate()
    try:
        search.setup(_BoxProblem(), termination=converged, seed=int(seed), verbose=False)
        history: list[float] = []
        while True:
            search.next()
            history.append(tally.best_f)
            if progress is not None:
                progress(len(history), tally.best_f)
            stopped_by = _stop_reason(tally.evaluations, clock, budget, search)
            if stopped_by is not None:
                break
    finally:
        np.random.set_state(np_state)
        random.setstate(py_state)

    assert tally.best_x is not None  # the first generation scores at least one candidate
    return SearchOutcome(
        x=tally.best_x,
        score=tally.best_f,
        evaluations=tally.evaluations,
        generations=len(history),
        best_by_generation=history,
        wall_s=time.perf_counter() - start,
        algorithm=algorithm,
        seed=int(seed),
        population=int(population),
        stopped_by=stopped_by,
    )


def _stop_reason(
    evaluations: int, clock: SolveClock | None, budget: SearchBudget, search: Any
) -> StopReason | None:
    """Why the search stops after this generation, in that order of precedence, or None."""
    if evaluations >= budget.max_evaluations:
        return "evaluations"
    if clock is not None and clock.expired() is not None:
        return "time"
    if search.termination.has_terminated():
        return "converged"
    return None
