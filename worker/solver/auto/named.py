"""A named method's second start: after a success in a class known to have separate local
optima (``local_optima``: a minimum heat load whose answer skips), the same method runs again
from another start (``runner.second_start``) and the better verified answer is kept, both
values compared in the result's ``cross_check`` and both runs listed in its ``attempts``, as
auto's cross-check does with a second method."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from app.schemas import ProblemDocument
from app.schemas.methods import ScpRunOptions
from worker.solver.auto.local_optima import SKIP_OBJECTIVES, skips
from worker.solver.auto.outcome import Attempt, better, compare
from worker.solver.auto.runner import MIN_ATTEMPT_S, SolveOne, second_start, tagged, unchecked
from worker.solver.methods.selection import Candidate, with_method
from worker.solver.result import validated


def second_start_wanted(problem: ProblemDocument, answer: dict[str, Any]) -> bool:
    """Whether a succeeded ``answer`` of a named method gets a second start: as
    ``method.second_start`` says, or, left null, for the objectives of
    :data:`~worker.solver.auto.local_optima.SKIP_OBJECTIVES` when the answer skips."""
    if answer.get("status") != "succeeded":
        return False
    choice = getattr(problem.method, "second_start", None)
    if choice is not None:
        return bool(choice)
    return not SKIP_OBJECTIVES.isdisjoint(problem.objective.names()) and skips(answer)


def with_second_start(
    problem: ProblemDocument,
    first: dict[str, Any],
    solve_one: SolveOne,
    hooks: dict[str, Any],
    cpu_start: float,
) -> dict[str, Any]:
    """``first`` (the result of ``problem``'s named method), or, when a second start is wanted
    (:func:`second_start_wanted`) and the method takes one, the better of the two runs with
    both in ``attempts``, ``cross_check`` and the history. The second run has what the first
    left of ``method.time_limit_s`` (CPU seconds since ``cpu_start``)."""
    if not second_start_wanted(problem, first):
        return first
    options = problem.method
    assert isinstance(options, ScpRunOptions)
    name = options.name
    history = first.get("history") or []
    one = Attempt(1, name, "answer", options.model_dump(mode="json"), first, 1, len(history))
    start = second_start(problem, Candidate(name, options, "the document names it"))
    left = options.time_limit_s - (time.process_time() - cpu_start)
    if start is None or left < MIN_ATTEMPT_S:
        why = "the method takes no second start" if start is None else "no time was left"
        note = f"a second start was wanted (a local optimum is possible) but {why}"
        return _assembled([one], one, unchecked(one, note), cpu_start)
    document, started, note = start
    started = started.model_copy(update={"time_limit_s": round(left, 3), "second_start": False})
    offset = len(history)
    sink: Callable[[dict[str, Any]], None] | None = hooks.get("on_iteration")

    def forward(record: dict[str, Any]) -> None:
        if sink is not None:
            sink(tagged(record, offset, 2, name))

    second = solve_one(with_method(document, started), **{**hooks, "on_iteration": forward})
    count = len(second.get("history") or [])
    two = Attempt(
        2, name, "cross_check", started.model_dump(mode="json"), second, offset + 1, count, note
    )
    kept = better(one, two) if two.succeeded else one
    return _assembled([one, two], kept, compare(one, two), cpu_start)


def _assembled(
    attempts: list[Attempt], kept: Attempt, cross: dict[str, Any], cpu_start: float
) -> dict[str, Any]:
    """``kept``'s result with every run's history (tagged), ``attempts``, ``cross_check`` and
    the runs' timing summed."""
    document = dict(kept.result)
    offset = 0
    combined: list[dict[str, Any]] = []
    for attempt in attempts:
        records = attempt.result.get("history") or []
        combined += [tagged(r, offset, attempt.index, attempt.name) for r in records]
        offset += len(records)
    document["history"] = combined
    document["attempts"] = [a.summary(a is kept) for a in attempts]
    document["cross_check"] = cross
    timings = [a.result.get("timing") or {} for a in attempts]
    document["timing"] = {
        **(kept.result.get("timing") or {}),
        **{
            key: float(sum(t.get(key) or 0.0 for t in timings))
            for key in ("wall_s", "conic_solve_s", "verification_s", "total_s")
        },
        "iterations": len(combined),
        "cpu_s": time.process_time() - cpu_start,
    }
    return validated(document)
