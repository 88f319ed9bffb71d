"""The one SCP driver every method runs on: budget, stop and time limit, conic failures,
history, accept/reject with rollback and the convergence gate.

A method supplies an ``ScpMethod`` (its hooks: start, linearize, subproblem, solve, propose,
judge) and gets back an ``ScpOutcome``. Each iteration linearizes about the reference (or reuses
the linearization its last judgement handed back), solves one convex subproblem, turns the
solution into a proposal (candidate reference + history record) and has the method judge it:
an accepted proposal becomes the reference, a rejected one leaves the reference where it was
(the method's judgement may hand back its linearization again). The driver declares
convergence only for an accepted step the method calls small whose virtual control is spent.
A proposal that diverges (non-finite numbers, or a step over the physical bounds of
``scp.divergence``) ends the run as ``failed`` with code ``diverged`` before the method judges
it: the reference stays the last sound one, so what is reported is finite. A subproblem with
non-finite data (a linearization that broke down) ends it as ``numerical_error``; so does a
conic solver's numerical failure, unless the method has a ``tighten`` hook (heavier trust
region, True when it could): then the subproblem about the same reference is solved again, at
most ``TIGHTEN_RETRIES`` times. The shape follows the usual SCP solver structure (e.g. the PTR
and SCvx drivers of SCPToolbox.jl): one loop, the method's numerics behind hooks.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Generic, Literal, Protocol, TypeVar

import numpy as np

from worker.solver.conic import ConeProblem, ConicBackend, ConicSolution, ConicStatus
from worker.solver.scp.divergence import divergence
from worker.solver.scp.history import IterationRecord
from worker.solver.solve_clock import SolveClock

ScpStatus = Literal["converged", "max_iterations", "failed", "cancelled", "timed_out"]
IterationSink = Callable[[IterationRecord], None]
StopCheck = Callable[[], bool]
ConicCall = Callable[[ConeProblem, float], ConicSolution]
"""Solve a conic problem within a time limit (s); the driver counts the solver time."""

VIRTUAL_CONTROL_TOL = 1e-6
"""Largest virtual-control norm (scaled units) of a step that may be called converged."""

Ref = TypeVar("Ref")
Lin = TypeVar("Lin")


class StartError(Exception):
    """The method cannot start (no initial guess, infeasible path limits): a failed outcome
    with ``code`` and the message, not a programming error."""

    def __init__(self, code: str, message: str, reference: Any = None) -> None:
        super().__init__(message)
        self.code = code
        self.reference = reference


@dataclass
class Proposal(Generic[Ref]):
    """A solved subproblem: the candidate reference and its history record."""

    reference: Ref
    record: IterationRecord


@dataclass
class Judgement(Generic[Ref, Lin]):
    """The method's verdict on a proposal.

    ``accepted``: the candidate becomes the reference (else the reference stays). ``small``: the
    step is below the method's stop tolerances (with whatever else the method requires, e.g. a
    settled objective). ``virtual_control``: the step's virtual-control norm. ``reference``
    replaces the candidate when the method changed it on acceptance (a new grid);
    ``linearization`` is the new reference's linearization when the judgement computed it
    (None: the driver linearizes at the next iteration). ``stalled``: why an accepted step ends
    the run unconverged (an infeasibility that no longer falls): failed, code ``infeasible``,
    with the node violations of the last reference as when the budget runs out.
    """

    accepted: bool
    small: bool = False
    virtual_control: float = 0.0
    reference: Ref | None = None
    linearization: Lin | None = None
    stalled: str | None = None


class ScpMethod(Protocol[Ref, Lin]):
    """What a method supplies to the driver (see the module docstring)."""

    def start(self) -> Ref:
        """The initial reference; raises ``StartError`` when the method cannot start."""
        ...

    def linearize(self, reference: Ref) -> Lin:
        """The linearization about ``reference`` (dynamics, constraints, cost gradients)."""
        ...

    def subproblem(self, reference: Ref, linearization: Lin, iteration: int) -> ConeProblem:
        """The convex subproblem of ``iteration`` (1-based) about ``reference``."""
        ...

    def solve(
        self,
        problem: ConeProblem,
        conic: ConicCall,
        limit_s: float,
        deadline: float,
    ) -> ConicSolution:
        """Solve ``problem`` through ``conic`` (a method may retry, e.g. with virtual control)."""
        ...

    def propose(
        self, reference: Ref, linearization: Lin, solution: ConicSolution, iteration: int
    ) -> Proposal[Ref]:
        """The candidate reference from a usable solution, with its history record."""
        ...

    def judge(self, reference: Ref, proposal: Proposal[Ref]) -> Judgement[Ref, Lin]:
        """Accept or reject the proposal; update the globalization (trust weights)."""
        ...


@dataclass
class ScpOutcome(Generic[Ref]):
    """What the driver produced: the status, the last reference and the history.

    ``history`` holds the records of the proposals the method judged; a diverging proposal's
    record is emitted (``on_iteration``) and kept in ``diverged`` instead, so that whatever a
    method reads from the history describes the reference it reports.
    """

    status: ScpStatus
    reference: Ref | None
    history: list[IterationRecord]
    failure_code: str | None = None
    failure_message: str | None = None
    conic_solve_s: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)
    diverged: IterationRecord | None = None


@dataclass(frozen=True)
class Budget:
    """Iteration and time budgets of one run (the method options' shared fields):
    ``time_limit_s`` in CPU seconds of the process (``solve_clock``), a conic solve's own limit
    in wall seconds."""

    max_iterations: int
    time_limit_s: float
    conic_time_limit_s: float | None = None

    def clock(self) -> SolveClock:
        """A clock of this budget's time limit, started now."""
        return SolveClock.start(self.time_limit_s)


def conic_limit(remaining_s: float, cap_s: float | None) -> float:
    """Time limit of one conic solve: what remains (capped), in whole seconds above 2 s (rounded
    down), so the limit rarely changes between iterations and the backend need not rebuild its
    settings; the driver itself checks the deadline before every iteration."""
    budget = remaining_s if cap_s is None else min(remaining_s, cap_s)
    return math.floor(budget) if budget > 2.0 else budget


_FAILURE_CODES = {ConicStatus.INFEASIBLE: "infeasible", ConicStatus.TIME_LIMIT: "time_limit"}
TIGHTEN_RETRIES = 3
"""Most re-solves of one iteration's subproblem under a heavier trust region (the method's
``tighten``) after the conic solver failed numerically on it."""


def _unsolved(solution: ConicSolution) -> bool:
    """A numerical failure of the conic solver (not an infeasible subproblem or its time
    limit): what a shorter step may cure."""
    failed = not solution.status.usable or solution.x is None
    return failed and solution.status not in _FAILURE_CODES


def _non_finite_data(problem: ConeProblem) -> str | None:
    """The first of the conic problem's data arrays that holds NaN or infinity, or None (the
    backend would refuse such data with an exception)."""
    arrays = [("q", problem.q), ("b", problem.b), ("A", problem.A.data)]
    if problem.P is not None:
        arrays.append(("P", problem.P.data))
    for name, values in arrays:
        if not np.isfinite(values).all():
            return name
    return None


def run_scp(
    method: ScpMethod[Ref, Lin],
    budget: Budget,
    backend: ConicBackend,
    *,
    on_iteration: IterationSink | None = None,
    should_stop: StopCheck | None = None,
    clock: SolveClock | None = None,
    offset: int = 0,
) -> ScpOutcome[Ref]:
    """Run ``method`` until it converges, fails, is stopped or runs out of its budget.

    ``clock`` measures ``budget.time_limit_s`` (default: started now; a multi-start run shares
    one); ``offset``: iterations of the history before this run (a later start of a multi-start
    run), by which the iterations its messages name are shifted into the history's numbering.
    """
    clock = clock or budget.clock()
    deadline = clock.wall_deadline
    history: list[IterationRecord] = []
    conic_total = 0.0

    def conic(problem: ConeProblem, limit_s: float) -> ConicSolution:
        nonlocal conic_total
        solution = backend.solve(problem, time_limit_s=limit_s)
        conic_total += solution.solve_time_s
        return solution

    try:
        reference = method.start()
    except StartError as exc:
        return ScpOutcome("failed", exc.reference, history, exc.code, str(exc))

    def outcome(
        status: ScpStatus, code: str | None = None, msg: str | None = None
    ) -> ScpOutcome[Ref]:
        return ScpOutcome(status, reference, history, code, msg, conic_total)

    linearization: Lin | None = None
    for it in range(1, budget.max_iterations + 1):
        it_start = time.perf_counter()
        if should_stop is not None and should_stop():
            return outcome("cancelled", "cancelled", f"cancelled before iteration {offset + it}")
        expired = clock.expired()
        if expired is not None:
            return outcome(
                "timed_out", "time_limit", f"{expired} reached after {it - 1} iterations"
            )
        if linearization is None:
            linearization = method.linearize(reference)
        problem = method.subproblem(reference, linearization, it)
        broken = _non_finite_data(problem)
        if broken is not None:
            return outcome(
                "failed",
                "numerical_error",
                f"iteration {offset + it}: the subproblem about the reference has non-finite "
                f"{broken} (the linearization broke down)",
            )
        limit = conic_limit(clock.remaining_s(), budget.conic_time_limit_s)
        solution = method.solve(problem, conic, limit, deadline)
        retries = 0
        tighten = getattr(method, "tighten", None)
        while _unsolved(solution) and tighten is not None and retries < TIGHTEN_RETRIES:
            if not tighten():
                break  # the trust region is as heavy as it gets
            retries += 1  # the same reference under a heavier trust region: a shorter step
            problem = method.subproblem(reference, linearization, it)
            limit = conic_limit(clock.remaining_s(), budget.conic_time_limit_s)
            solution = method.solve(problem, conic, limit, deadline)
        if not solution.status.usable or solution.x is None:
            code = _FAILURE_CODES.get(solution.status, "numerical_error")
            return outcome(
                "timed_out" if code == "time_limit" else "failed",
                code,
                f"iteration {offset + it}: convex subproblem {solution.status.value} "
                f"({solution.solver}: {solution.raw_status})",
            )
        proposal = method.propose(reference, linearization, solution, it)
        if retries:
            proposal.record.extra["subproblem_retries"] = retries
        diverged = divergence(proposal.reference, proposal.record)
        if diverged is not None:
            proposal.record.iteration_wall_s = time.perf_counter() - it_start
            if on_iteration is not None:
                on_iteration(proposal.record)
            done = outcome("failed", "diverged", f"diverged at {diverged}")
            done.diverged = proposal.record
            return done
        verdict = method.judge(reference, proposal)
        if verdict.accepted:
            reference = verdict.reference if verdict.reference is not None else proposal.reference
        linearization = verdict.linearization
        proposal.record.iteration_wall_s = time.perf_counter() - it_start
        history.append(proposal.record)
        if on_iteration is not None:
            on_iteration(proposal.record)
        if verdict.accepted and verdict.small and verdict.virtual_control <= VIRTUAL_CONTROL_TOL:
            return outcome("converged")
        if verdict.accepted and verdict.stalled is not None:  # judged as a spent budget
            return outcome("max_iterations", "infeasible", verdict.stalled)
    return outcome(
        "max_iterations",
        "max_iterations",
        f"not converged in {budget.max_iterations} iterations",
    )
