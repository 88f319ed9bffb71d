"""Initial guesses of the phased collocation: the global search of ``phase_search`` (GA or PSO,
paper 004 sec. 2.2-2.4) priced with the NLP's objective, or constant controls, sampled at every
phase's mesh points."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from worker.solver.global_search import SearchBudget, SearchOutcome
from worker.solver.methods.lgl_sqp.nlp import PhasedNlp
from worker.solver.phase_search import (
    FINE_STEPS,
    ObjectiveOf,
    Parameterization,
    fly,
    score,
    search_phases,
)

Array = np.ndarray


def nlp_objective(nlp: PhasedNlp) -> ObjectiveOf:
    """The NLP's (linear) objective of candidates from their final states and durations."""

    def objective(end: Array, durations: Array) -> Array:
        zs = np.zeros((end.shape[0], nlp.n))
        last = nlp.slots[-1]
        end_at = last.x0 + (last.mesh.points - 1) * nlp.nx
        zs[:, end_at : end_at + nlp.nx] = end
        for p, slot in enumerate(nlp.slots):
            zs[:, slot.tau] = durations[:, p]
        result: Array = zs @ nlp.objective_gradient + nlp.objective_offset
        return result

    return objective


@dataclass
class Guess:
    """Each phase's states, controls and duration at its mesh points, and how they were found."""

    states: list[Array]
    controls: list[Array]
    durations: list[float]
    params: Array
    score: float
    search: SearchOutcome | None


def guess_on_mesh(par: Parameterization, nlp: PhasedNlp, params: Array) -> Guess:
    """The candidate ``params`` flown finely and sampled at every phase's mesh points."""
    flights = fly(par, params[None, :], FINE_STEPS)
    xs, us, taus = [], [], []
    for p, (s_grid, x, u) in enumerate(flights):
        s = nlp.slots[p].mesh.s
        xs.append(np.column_stack([np.interp(s, s_grid, x[:, 0, i]) for i in range(nlp.nx)]))
        us.append(par.controls(np.repeat(params[None, :], s.size, axis=0), p, s))
        taus.append(float(par.duration(params[None, :], p)[0]))
        del u
    sc = float(score(par, params[None, :], objective=nlp_objective(nlp))[0])
    return Guess(xs, us, taus, params, sc, None)


def global_guess(
    par: Parameterization,
    nlp: PhasedNlp,
    *,
    algorithm: str,
    seed: int,
    population: int,
    budget: SearchBudget,
    progress: Callable[[int, float], None] | None = None,
) -> Guess:
    """The best candidate of ``phase_search.search_phases`` priced with the NLP's objective,
    sampled at every phase's mesh points."""
    outcome = search_phases(
        par,
        algorithm=algorithm,
        seed=seed,
        population=population,
        budget=budget,
        objective=nlp_objective(nlp),
        progress=progress,
    )
    guess = guess_on_mesh(par, nlp, outcome.x)
    guess.search = outcome
    return guess
