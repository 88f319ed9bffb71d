"""The seeded, budgeted global search (pymoo's GA and PSO, real runs on analytic functions):
it finds known minima, repeats itself bit for bit under a seed, keeps to its budget, ranks
failed candidates worst, reports each generation, validates its inputs and leaves the caller's
random state alone."""

from __future__ import annotations

import itertools
import random
import time
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest

from worker.solver.global_search import Algorithm, SearchBudget, SearchOutcome, global_search

Array = npt.NDArray[np.float64]
ALGORITHMS: tuple[Algorithm, ...] = ("ga", "pso")

CENTER = np.array([0.3, -1.2, 2.0, 0.7])
LOWER4, UPPER4 = np.full(4, -5.0), np.full(4, 5.0)
SHIFT = np.array([1.3, -0.7])
LOWER2, UPPER2 = np.full(2, -5.12), np.full(2, 5.12)


def sphere(X: Array) -> Array:
    """Shifted sphere in 4-D: minimum 0 at CENTER."""
    return np.asarray(np.sum((X - CENTER) ** 2, axis=1))


def rastrigin(X: Array) -> Array:
    """Shifted 2-D Rastrigin: minimum 0 at SHIFT, a local minimum near every other integer
    offset from it (about a hundred in the box)."""
    Z = X - SHIFT
    return np.asarray(20.0 + np.sum(Z**2 - 10.0 * np.cos(2.0 * np.pi * Z), axis=1))


class Recording:
    """A scorer that keeps every population it was given (copies), for the path of a search."""

    def __init__(self, f: Any) -> None:
        self.f = f
        self.calls: list[Array] = []

    def __call__(self, X: Array) -> Array:
        self.calls.append(X.copy())
        return np.asarray(self.f(X), dtype=np.float64)

    @property
    def rows(self) -> int:
        return sum(len(X) for X in self.calls)


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_both_searches_reach_the_minimum_of_a_shifted_sphere(algorithm: Algorithm) -> None:
    """Within 0.02 per component (0.2 % of the box's width 10) and 1e-3 in score, after the
    default 4000 evaluations: pymoo's GA with its default SBX and polynomial mutation refines
    to a few thousandths at this budget (seeds 0-4 land within 0.006; PSO within 1e-4); the
    search only has to start a local optimization inside the right basin."""
    scorer = Recording(sphere)
    out = global_search(scorer, LOWER4, UPPER4, algorithm=algorithm, seed=1)
    np.testing.assert_allclose(out.x, CENTER, rtol=0, atol=0.02)
    assert 0.0 <= out.score <= 1e-3
    assert out.score == float(sphere(out.x[None, :])[0])
    assert out.evaluations == scorer.rows
    assert out.stopped_by in ("evaluations", "converged")
    every = np.vstack(scorer.calls)
    assert np.all(every >= LOWER4) and np.all(every <= UPPER4)  # candidates stay in the box


def test_the_ga_finds_the_global_basin_among_local_minima() -> None:
    """Seed 3: the answer lies within 0.1 of the global minimum (neighbouring local minima are
    1 apart, each scoring at least 1), where the initial population's best is elsewhere."""
    scorer = Recording(rastrigin)
    out = global_search(scorer, LOWER2, UPPER2, algorithm="ga", seed=3, budget=SearchBudget(2000))
    first_best = scorer.calls[0][int(np.argmin(rastrigin(scorer.calls[0])))]
    assert np.max(np.abs(first_best - SHIFT)) > 0.5  # not found by the random start alone
    np.testing.assert_allclose(out.x, SHIFT, rtol=0, atol=0.1)
    assert out.score < 0.5


def _same(a: SearchOutcome, b: SearchOutcome) -> bool:
    return (
        a.x.tobytes() == b.x.tobytes()
        and a.score == b.score
        and a.evaluations == b.evaluations
        and a.generations == b.generations
        and a.best_by_generation == b.best_by_generation
        and a.stopped_by == b.stopped_by
    )


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_a_seed_repeats_the_search_bit_for_bit_and_another_seed_takes_another_path(
    algorithm: Algorithm,
) -> None:
    budget = SearchBudget(max_evaluations=600)
    runs = []
    for seed in (7, 7, 8):
        scorer = Recording(rastrigin)
        out = global_search(
            scorer, LOWER2, UPPER2, algorithm=algorithm, seed=seed, population=20, budget=budget
        )
        runs.append((out, scorer.calls))
    (a, calls_a), (b, calls_b), (c, calls_c) = runs
    assert _same(a, b)
    assert len(calls_a) == len(calls_b)
    assert all(x.tobytes() == y.tobytes() for x, y in zip(calls_a, calls_b, strict=True))
    assert calls_a[0].tobytes() != calls_c[0].tobytes()  # another start
    assert a.best_by_generation != c.best_by_generation
    assert (a.seed, c.seed, a.algorithm, a.population) == (7, 8, algorithm, 20)


@pytest.mark.parametrize("algorithm", ALGORITHMS)
@pytest.mark.parametrize(("max_evaluations", "generations"), [(130, 4), (10, 1), (120, 3)])
def test_the_evaluation_budget_stops_after_whole_generations(
    algorithm: Algorithm, max_evaluations: int, generations: int
) -> None:
    """One scorer call per generation, of at most a population (exactly one for PSO, and for
    the GA's first generation); the search stops at the first generation that reaches the
    budget, so it passes it by less than a population."""
    scorer = Recording(sphere)
    out = global_search(
        scorer,
        LOWER4,
        UPPER4,
        algorithm=algorithm,
        seed=0,
        population=40,
        budget=SearchBudget(max_evaluations=max_evaluations),
    )
    assert out.stopped_by == "evaluations"
    assert out.evaluations == scorer.rows
    assert max_evaluations <= out.evaluations < max_evaluations + 40
    assert len(scorer.calls) == out.generations == generations == len(out.best_by_generation)
    assert scorer.calls[0].shape == (40, 4)
    assert all(X.ndim == 2 and X.shape[1] == 4 and len(X) <= 40 for X in scorer.calls)
    if algorithm == "pso":
        assert out.evaluations == 40 * generations


def test_the_time_limit_stops_a_search_between_generations() -> None:
    """Each generation takes 20 ms of CPU time; a 0.1 s limit (CPU seconds) ends the search
    after about five of them, far before its 4000 evaluations (100 generations, 2 s)."""

    def slow(X: Array) -> Array:
        end = time.process_time() + 0.02
        while time.process_time() < end:
            pass
        return sphere(X)

    out = global_search(
        slow, LOWER4, UPPER4, algorithm="ga", seed=0, budget=SearchBudget(time_limit_s=0.1)
    )
    assert out.stopped_by == "time"
    assert 0.1 <= out.wall_s < 1.0  # the limit plus one generation (loose: a busy machine)
    assert 1 <= out.generations <= 5  # five generations take at least 0.1 s of CPU time
    assert out.evaluations < 4000


def test_a_search_that_waits_is_ended_by_the_wall_clock_safety() -> None:
    """A scorer that sleeps spends no CPU time: the wall-clock safety (4 x the 0.1 s limit)
    ends the search, by time, after about 0.4 s. Each generation sleeps 0.1 s so the
    search's own CPU (a few ms a generation) stays far below the 0.1 s CPU limit by then."""

    def waiting(X: Array) -> Array:
        time.sleep(0.1)
        return sphere(X)

    out = global_search(
        waiting, LOWER4, UPPER4, algorithm="ga", seed=0, budget=SearchBudget(time_limit_s=0.1)
    )
    assert out.stopped_by == "time"
    assert 0.4 <= out.wall_s < 2.0
    assert out.evaluations < 4000


def test_nan_scores_count_as_the_worst() -> None:
    """The scorer fails (nan) within 0.5 of a 2-D sphere's centre, where it would score lowest:
    the answer is a finite score on the rim of that hole (0.25 at best), never a failed
    candidate (numpy's argmin would pick a nan first)."""

    def failing_near_center(X: Array) -> Array:
        f = np.sum((X - SHIFT) ** 2, axis=1)
        return np.where(f < 0.25, np.nan, f)

    for algorithm in ALGORITHMS:
        scorer = Recording(failing_near_center)
        out = global_search(
            scorer, LOWER2, UPPER2, algorithm=algorithm, seed=0, budget=SearchBudget(1000)
        )
        assert sum(int(np.isnan(scorer.f(X)).sum()) for X in scorer.calls) > 50  # many failed
        assert 0.25 <= out.score < 0.26
        assert np.linalg.norm(out.x - SHIFT) >= 0.5
        assert all(np.isfinite(out.best_by_generation))


def test_a_search_where_every_candidate_fails_scores_inf() -> None:
    out = global_search(
        lambda X: np.full(len(X), np.nan),
        LOWER2,
        UPPER2,
        algorithm="pso",
        seed=0,
        population=10,
        budget=SearchBudget(50),
    )
    assert out.score == np.inf
    assert out.x.shape == (2,) and np.all(out.x >= LOWER2) and np.all(out.x <= UPPER2)
    assert out.best_by_generation == [np.inf] * out.generations


def test_progress_sees_each_generation_with_the_best_score_so_far() -> None:
    seen: list[tuple[int, float]] = []
    out = global_search(
        rastrigin,
        LOWER2,
        UPPER2,
        algorithm="ga",
        seed=2,
        population=20,
        budget=SearchBudget(400),
        progress=lambda generation, best: seen.append((generation, best)),
    )
    assert [g for g, _ in seen] == list(range(1, out.generations + 1))
    bests = [b for _, b in seen]
    assert bests == out.best_by_generation
    assert all(later <= earlier for earlier, later in itertools.pairwise(bests))
    assert bests[-1] == out.score
    assert bests[0] > bests[-1]  # it did improve on the initial population


def test_an_exception_in_progress_aborts_the_search() -> None:
    class AbortError(Exception):
        pass

    def stop_at_third(generation: int, best: float) -> None:
        if generation == 3:
            raise AbortError

    scorer = Recording(sphere)
    with pytest.raises(AbortError):
        global_search(scorer, LOWER4, UPPER4, algorithm="pso", seed=0, progress=stop_at_third)
    assert len(scorer.calls) == 3


def test_a_search_converges_before_a_large_budget() -> None:
    """PSO on a 2-D sphere settles (pymoo's test: 30 generations in a row none of which gains
    more than 1e-6) long before 20000 evaluations."""
    out = global_search(
        lambda X: np.sum((X - SHIFT) ** 2, axis=1),
        LOWER2,
        UPPER2,
        algorithm="pso",
        seed=0,
        population=20,
        budget=SearchBudget(20000),
    )
    assert out.stopped_by == "converged"
    assert out.evaluations < 20000
    assert out.generations >= 30
    np.testing.assert_allclose(out.x, SHIFT, rtol=0, atol=1e-3)


def test_the_callers_random_state_is_untouched() -> None:
    """numpy's and Python's global generators draw after a search what they would have drawn
    without it (pymoo 0.6.2 keeps its own generator; older releases reseeded the global ones)."""
    np.random.seed(12345)
    random.seed(12345)
    expected = np.random.random(3), random.random()
    np.random.seed(12345)
    random.seed(12345)
    for algorithm in ALGORITHMS:
        global_search(
            sphere, LOWER4, UPPER4, algorithm=algorithm, seed=99, budget=SearchBudget(200)
        )
    assert np.array_equal(np.random.random(3), expected[0])
    assert random.random() == expected[1]


def _run(**overrides: Any) -> SearchOutcome:
    kwargs: dict[str, Any] = {
        "score": sphere,
        "lower": LOWER4,
        "upper": UPPER4,
        "algorithm": "ga",
        "seed": 0,
        "population": 10,
        "budget": SearchBudget(20),
    }
    kwargs.update(overrides)
    return global_search(**kwargs)


@pytest.mark.parametrize(
    ("overrides", "named"),
    [
        ({"lower": np.array([0.0, 0.0, 1.0, 0.0]), "upper": np.array([1.0, 1.0, 1.0, 1.0])},
         "lower"),
        ({"lower": np.full(4, 2.0), "upper": np.full(4, 1.0)}, "lower"),
        ({"upper": np.full(3, 5.0)}, "upper"),
        ({"lower": np.array([-1.0, np.nan, -1.0, -1.0])}, "lower"),
        ({"upper": np.array([1.0, np.inf, 1.0, 1.0])}, "upper"),
        ({"lower": np.zeros((2, 2)), "upper": np.ones((2, 2))}, "lower"),
        ({"lower": np.zeros(0), "upper": np.zeros(0)}, "lower"),
        ({"population": 1}, "population"),
        ({"population": 2.5}, "population"),
        ({"algorithm": "de"}, "algorithm"),
        ({"seed": -1}, "seed"),
        ({"seed": 1.5}, "seed"),
        ({"score": lambda X: np.zeros((len(X), 1))}, "score"),
    ],
)  # fmt: skip
def test_invalid_inputs_raise_a_value_error_naming_the_argument(
    overrides: dict[str, Any], named: str
) -> None:
    with pytest.raises(ValueError, match=rf"^{named} must"):
        _run(**overrides)


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"max_evaluations": 0}, "max_evaluations"),
        ({"max_evaluations": 10.0}, "max_evaluations"),
        ({"time_limit_s": 0.0}, "time_limit_s"),
        ({"time_limit_s": float("nan")}, "time_limit_s"),
    ],
)
def test_an_unspendable_budget_raises_a_value_error_naming_the_field(
    kwargs: dict[str, Any], named: str
) -> None:
    with pytest.raises(ValueError, match=rf"^{named} must"):
        SearchBudget(**kwargs)
