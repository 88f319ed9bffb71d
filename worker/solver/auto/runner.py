"""Run ``auto``: the methods that accept the problem, in auto's order, within one time budget.

Each attempt is a whole solve of the problem with one method (its optimization, verification
and advice) and gets what the earlier attempts left of ``method.time_limit_s``. The first that
succeeds (converged and verified) is the answer; a failure passes to the next method, at most
``max_attempts``. With a cross-check (``cross_check``, by default on for the classes of
``local_optima``) the next methods that accept the problem run after a success until one
succeeds (at most two; with none left, the same method from a second start) and both values
are reported.
A stop (cancellation, the job's time limit) or the budget running out ends the whole run.
The history holds every attempt's iterations numbered on, each tagged with its attempt.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from pydantic import ValidationError

from app.schemas import ProblemDocument
from app.schemas.methods import AutoOptions, ScpRunOptions
from app.schemas.plausibility import plausibility_warnings
from worker.solver.auto.document import assemble, refused
from worker.solver.auto.local_optima import cross_check_wanted
from worker.solver.auto.outcome import Attempt, Purpose, better, compare
from worker.solver.methods import registry
from worker.solver.methods.selection import Candidate, Selection, select, with_method
from worker.solver.result import input_provenance, validated
from worker.solver.solve_clock import WALL_FACTOR, SolveClock

MIN_ATTEMPT_S = 1.0
"""Least time worth starting a further attempt with, s; with less left the run ends (the
first attempt has the whole budget)."""
MAX_CROSS_CHECK_RUNS = 2
"""Most methods run for a cross-check: the next after the answer's, and one more when that one
fails (Betts' Shuttle from a 60 deg heading, when cheb-scvx answered it: hp-scp stopped at its
iteration limit, lgl-sqp then found the better optimum; docs/problem-contract.md)."""


class SolveOne(Protocol):
    """A solve of a document that names its method (``api.solve_problem``)."""

    def __call__(
        self,
        problem: ProblemDocument,
        *,
        on_iteration: Callable[[dict[str, Any]], None] | None = ...,
        should_stop: Callable[[], bool] | None = ...,
        on_phase: Callable[[str], None] | None = ...,
        on_kernels: Callable[[Any], None] | None = ...,
    ) -> dict[str, Any]: ...


def tagged(record: dict[str, Any], offset: int, index: int, name: str) -> dict[str, Any]:
    """An attempt's history record numbered on from the attempts before it and tagged."""
    extra = {**(record.get("extra") or {}), "auto_attempt": index, "method": name}
    return {**record, "iteration": int(record["iteration"]) + offset, "extra": extra}


class AutoRun:
    """One run of auto on a problem: its clock, its attempts, the combined history."""

    def __init__(
        self, problem: ProblemDocument, solve_one: SolveOne, hooks: dict[str, Any]
    ) -> None:
        assert isinstance(problem.method, AutoOptions)
        self.problem = problem
        self.auto: AutoOptions = problem.method
        self.solve_one = solve_one
        self.hooks = hooks
        self.clock = SolveClock.start(self.auto.time_limit_s)
        self.attempts: list[Attempt] = []
        self.history: list[dict[str, Any]] = []
        self.stop: str | None = None

    def left(self) -> float:
        """CPU seconds left of auto's budget (``time_limit_s`` counts CPU time, as every
        method's does), less when the wall-clock safety of the whole run is nearer."""
        cpu_left = self.clock.cpu_limit_s - self.clock.cpu_used_s()
        return min(cpu_left, self.clock.remaining_s() / WALL_FACTOR)

    def run(
        self,
        name: str,
        options: ScpRunOptions,
        purpose: Purpose,
        document: ProblemDocument | None = None,
        start_note: str | None = None,
    ) -> Attempt | None:
        """Run method ``name`` (on ``document`` when given: a second start); None when too
        little time is left to start it. Sets ``stop`` when the run must end."""
        left = self.left()
        if self.attempts and left < MIN_ATTEMPT_S:
            self.stop = "timed_out"
            return None
        own = options.time_limit_s if "time_limit_s" in self.auto.overrides.get(name, {}) else None
        limit = round(left if own is None else min(own, left), 3)
        # auto's own cross-check looks for other optima: no named second start inside it
        chosen = self.auto.overrides.get(name, {})
        update: dict[str, Any] = {"time_limit_s": limit}
        if "second_start" not in chosen:
            update["second_start"] = False
        options = options.model_copy(update=update)
        doc = with_method(document or self.problem, options)
        index, offset = len(self.attempts) + 1, len(self.history)
        sink = self.hooks.get("on_iteration")

        def forward(record: dict[str, Any]) -> None:
            if sink is not None:
                sink(tagged(record, offset, index, name))

        result = self.solve_one(doc, **{**self.hooks, "on_iteration": forward})
        records = [tagged(r, offset, index, name) for r in result.get("history") or []]
        self.history += records
        attempt = Attempt(
            index,
            name,
            purpose,
            options.model_dump(mode="json"),
            result,
            offset + 1,
            len(records),
            start_note,
        )
        self.attempts.append(attempt)
        if attempt.status == "cancelled":
            self.stop = "cancelled"
        elif attempt.status == "timed_out" and limit >= left:
            self.stop = "timed_out"
        return attempt


def second_start(
    problem: ProblemDocument, candidate: Candidate
) -> tuple[ProblemDocument, ScpRunOptions, str] | None:
    """The same method from another start, when it takes one: lgl-sqp's global search with the
    next seed (or a global search instead of its constant guess); any other method the
    problem-level global search (``initial_guess: {"kind": "global"}``) when the problem gives
    no start of its own. None when the method takes none."""
    options = candidate.options
    search = getattr(options, "global_guess", None)
    if search is not None:
        if getattr(options, "initial_guess", None) == "global":
            seed = search.seed + 1
            update = {"global_guess": search.model_copy(update={"seed": seed})}
            note = f"its own global search with seed {seed}"
        else:
            update, note = {"initial_guess": "global"}, "its own global search"
        return problem, options.model_copy(update=update), note
    if problem.initial_guess is not None:
        return None
    document = problem.model_dump(mode="json")
    document["initial_guess"] = {"kind": "global"}
    try:
        started = with_method(ProblemDocument.model_validate(document), options)
    except ValidationError:
        return None
    if registry.check_support(started):
        return None
    return started, options, "the global search's start (initial_guess kind global)"


def _cross_check(run: AutoRun, kept: Attempt, selection: Selection) -> dict[str, Any]:
    """Run the cross-check after ``kept`` succeeded and compare the two values: the methods
    after it in auto's order until one succeeds (at most ``MAX_CROSS_CHECK_RUNS``), else the
    same method from a second start."""
    tried = {a.name for a in run.attempts}
    following = [c for c in selection.candidates if c.name not in tried]
    other: Attempt | None = None
    for candidate in following[:MAX_CROSS_CHECK_RUNS]:
        ran = run.run(candidate.name, candidate.options, "cross_check")
        if ran is None:
            break
        other = ran
        if ran.succeeded or run.stop is not None:
            break
    if not following:
        chosen = next(c for c in selection.candidates if c.name == kept.name)
        start = second_start(run.problem, chosen)
        if start is None:
            return unchecked(
                kept, "no other method accepts the problem and the method takes no second start"
            )
        document, options, note = start
        other = run.run(kept.name, options, "cross_check", document, note)
    if other is None:
        return unchecked(kept, "no time was left for a cross-check")
    return compare(kept, other)


def unchecked(kept: Attempt, why: str) -> dict[str, Any]:
    """The ``cross_check`` entry of a run that made none."""
    return {
        "attempts": [kept.index],
        "methods": [kept.name],
        "values": [kept.objective],
        "relative_difference": None,
        "agree": None,
        "warning": None,
        "note": why,
    }


def solve_auto(problem: ProblemDocument, solve_one: SolveOne, **hooks: Any) -> dict[str, Any]:
    """Solve ``problem`` (method auto) and return its result document: the kept answer's, with
    every attempt (``attempts``), the combined history, the cross-check and why auto chose."""
    run = AutoRun(problem, solve_one, hooks)
    selection = select(problem)
    if not selection.candidates:
        return refused(problem, selection)
    kept: Attempt | None = None
    for candidate in selection.candidates[: run.auto.max_attempts]:
        attempt = run.run(candidate.name, candidate.options, "answer")
        if attempt is not None and attempt.succeeded:
            kept = attempt
            break
        if run.stop is not None:
            break
    cross: dict[str, Any] | None = None
    if kept is not None and cross_check_wanted(problem, kept.result) and run.stop is None:
        cross = _cross_check(run, kept, selection)
        other = run.attempts[-1]
        if other is not kept and other.succeeded:
            kept = better(kept, other)
    return validated(
        assemble(
            run, selection, kept, cross, input_provenance(problem), plausibility_warnings(problem)
        )
    )
