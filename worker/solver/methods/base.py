"""What every method is and returns: ``MethodInfo`` (the registry entry), ``MethodResult``, and
the support checks methods share (field issues for features they cannot handle)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Generic, Protocol, TypedDict, TypeVar

from app.schemas import FieldIssue, ProblemDocument
from app.schemas.methods import ScpRunOptions
from worker.solver.conic import ConicBackend, make_backend
from worker.solver.problem import EntryProblem
from worker.solver.scp.history import IterationRecord
from worker.solver.scp.loop import (
    Budget,
    IterationSink,
    ScpMethod,
    ScpOutcome,
    ScpStatus,
    StopCheck,
    run_scp,
)
from worker.solver.solve_clock import SolveClock
from worker.solver.trajectory import OptimizedTrajectory, PhasedTrajectory

Options = TypeVar("Options", bound=ScpRunOptions)
Ref = TypeVar("Ref")
SupportCheck = Callable[[ProblemDocument], list[FieldIssue]]

FINAL_EXTREMES = (
    "max_final_latitude",
    "min_final_latitude",
    "max_final_longitude",
    "min_final_longitude",
)
"""Objectives on the last node's latitude or longitude, which every method supports."""

MODEL_FEATURES = (
    "terminal conditions fixed, range, free or soft",
    "rotating or non-rotating planet",
    "exponential or US76 atmosphere",
    "polynomial or tabulated aerodynamics with a scheduled angle of attack",
)
"""Features of the problem model that every method supports."""


@dataclass
class MethodResult:
    """Status, the optimized trajectory (None when no iteration finished), and the history.

    ``objective_terms`` holds each objective term's value on the final trajectory in SI units
    (J/m^2, s, m/s, deg), keyed by term name.
    """

    status: ScpStatus
    trajectory: OptimizedTrajectory | PhasedTrajectory | None
    history: list[IterationRecord]
    conic_solve_s: float
    objective_terms: dict[str, float] = field(default_factory=dict)
    failure_code: str | None = None
    failure_message: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    starts: list[dict[str, Any]] | None = None
    """One summary per start of a multi-start run (``run_starts``); None for a single start."""
    final_record: IterationRecord | None = None
    """The kept start's last iteration when the history holds several starts."""
    verification: dict[str, Any] | None = None
    """The verification report of ``trajectory`` when the method already flew it (the problem it
    was given, the same controls): the caller reuses it instead of flying it again."""
    verification_s: float = 0.0
    """Wall seconds the method spent on ``verification``."""

    @property
    def last_record(self) -> IterationRecord | None:
        """The last iteration of the run whose trajectory is the result."""
        if self.final_record is not None:
            return self.final_record
        return self.history[-1] if self.history else None


class RunHooks(TypedDict, total=False):
    """What a caller may hand a method's ``run``: the history sink, the stop check, and a conic
    backend that replaces the options' one (tests)."""

    on_iteration: IterationSink | None
    should_stop: StopCheck | None
    backend: ConicBackend | None


class DrivenMethod(ScpMethod[Ref, Any], Protocol):
    """A method's hooks plus what turns the driver's outcome into a method result."""

    extra: dict[str, Any]

    def trajectory(self, reference: Ref) -> OptimizedTrajectory:
        """The reference as a trajectory to verify and report."""
        ...

    def objective_terms(self, outcome: ScpOutcome[Ref]) -> dict[str, float]:
        """Each objective term's value (SI) on the outcome's trajectory."""
        ...


def run_method(
    build: Callable[[], DrivenMethod[Ref]],
    options: ScpRunOptions,
    hooks: RunHooks,
    *,
    clock: SolveClock | None = None,
    offset: int = 0,
) -> MethodResult:
    """Build a method (its set-up counts against the time limit) and run it on the shared driver
    with the budgets and conic backend of its options; ``clock``: the time limit's clock
    (default: started now, CPU seconds); ``offset``: iterations of the history before this run
    (its messages name iterations in the history's numbering)."""
    budget = Budget(options.max_iterations, options.time_limit_s, options.conic_time_limit_s)
    clock = clock or budget.clock()
    method = build()
    backend = hooks.get("backend") or make_backend(
        options.conic_backend, fallback=options.fallback_solver
    )
    outcome = run_scp(
        method,
        budget,
        backend,
        on_iteration=hooks.get("on_iteration"),
        should_stop=hooks.get("should_stop"),
        clock=clock,
        offset=offset,
    )
    ref = outcome.reference
    # a method that verified its last reference on the way hands the report on (optional hook)
    hook: Callable[[Ref], tuple[dict[str, Any], float] | None] | None
    hook = getattr(method, "flown_report", None)
    flown = hook(ref) if hook is not None and ref is not None else None
    return MethodResult(
        status=outcome.status,
        trajectory=method.trajectory(ref) if ref is not None and outcome.history else None,
        verification=flown[0] if flown is not None else None,
        verification_s=flown[1] if flown is not None else 0.0,
        history=outcome.history,
        conic_solve_s=outcome.conic_solve_s,
        objective_terms=method.objective_terms(outcome),
        failure_code=outcome.failure_code,
        failure_message=outcome.failure_message,
        extra=dict(method.extra),
    )


def run_starts(
    builds: Sequence[Callable[[], DrivenMethod[Ref]]],
    options: ScpRunOptions,
    hooks: RunHooks,
    cost: Callable[[MethodResult], float],
    labels: Sequence[dict[str, Any]],
) -> MethodResult:
    """Run the same method from several starts, one after the other, and keep the best answer.

    A converged start beats one that is not, and among the converged the lowest ``cost`` wins;
    when none converged the first start's outcome is the result (its failure is the one
    reported). The time limit covers all starts and ``max_iterations`` applies to each; the
    history holds every start's iterations numbered on from one start to the next, each record
    tagged with its start (``extra.start``, 1-based) and that start's ``labels`` entry. A start
    that is cancelled or runs out of time ends the run, and reports it when no start converged.
    The failure message of a run of several starts names the start it is about and where that
    start's iterations are in the history.
    """
    clock = SolveClock.start(options.time_limit_s)
    sink = hooks.get("on_iteration")
    results: list[MethodResult] = []
    offset = 0
    for index, build in enumerate(builds):
        tag = {"start": index + 1, **labels[index]}

        def tagged(
            record: IterationRecord, shift: int = offset, tag: dict[str, Any] = tag
        ) -> IterationRecord:
            return replace(
                record, iteration=record.iteration + shift, extra={**record.extra, **tag}
            )

        seen: list[IterationRecord] = []

        def forward(
            record: IterationRecord,
            mark: Callable[..., IterationRecord] = tagged,
            streamed: list[IterationRecord] = seen,
        ) -> None:
            streamed.append(mark(record))
            if sink is not None:
                sink(streamed[-1])

        run_hooks: RunHooks = {**hooks, "on_iteration": forward}
        result = run_method(build, options, run_hooks, clock=clock, offset=offset)
        # the driver streams every record of its history, in order, and a diverging one that
        # it does not keep: the streamed records are the history, that one kept with its start
        result.history = seen
        results.append(result)
        offset += len(result.history)
        if result.status in ("cancelled", "timed_out"):
            break
    converged = [r for r in results if r.status == "converged"]
    stopped = results[-1].status in ("cancelled", "timed_out")
    chosen = min(converged, key=cost) if converged else results[-1 if stopped else 0]
    history = [record for r in results for record in r.history]
    message = chosen.failure_message
    if message and len(builds) > 1:
        message = f"{start_label(results.index(chosen), len(builds), chosen.history)}: {message}"
    summaries = [
        {
            **labels[i],
            "start": i + 1,
            "status": r.status,
            "iterations": len(r.history),
            "objective_terms": r.objective_terms,
            "chosen": r is chosen,
        }
        for i, r in enumerate(results)
    ]
    return replace(
        chosen,
        history=history,
        conic_solve_s=sum(r.conic_solve_s for r in results),
        starts=summaries,
        final_record=chosen.history[-1] if chosen.history else None,
        failure_message=message,
    )


def start_label(index: int, starts: int, history: Sequence[IterationRecord]) -> str:
    """Which start of a multi-start run a message is about (``index`` 0-based), and where its
    iterations are in the run's history."""
    if not history:
        return f"start {index + 1} of {starts} (no iteration)"
    first, last = history[0].iteration, history[-1].iteration
    where = f"history iteration {first}" if first == last else f"history iterations {first}-{last}"
    return f"start {index + 1} of {starts} ({where})"


class Runner(Generic[Options]):
    """Runs a method with its own options type: ``run(problem, options, on_iteration,
    should_stop)``; the method's module is imported on first use (keeps start-up light)."""

    def __init__(self, module: str, options_type: type[Options]) -> None:
        self.module = module
        self.options_type = options_type

    def __call__(
        self,
        problem: EntryProblem,
        options: ScpRunOptions,
        on_iteration: IterationSink | None = None,
        should_stop: StopCheck | None = None,
    ) -> MethodResult:
        """Run the method (``options`` must be its own options model)."""
        import importlib

        if not isinstance(options, self.options_type):
            raise TypeError(f"{self.module} needs {self.options_type.__name__}")
        run = importlib.import_module(self.module).run
        result: MethodResult = run(
            problem, options, on_iteration=on_iteration, should_stop=should_stop
        )
        return result


@dataclass(frozen=True)
class MethodInfo:
    """A selectable method: its name, what it is, where it comes from, what it supports."""

    name: str
    title: str
    paper: str
    features: tuple[str, ...]
    objectives: tuple[str, ...]
    options_type: type[ScpRunOptions]
    check: SupportCheck
    run: Runner[Any]
    warm_kernels: bool = False
    """Whether the method's loop runs the compiled kernels whose loading (a few tenths of a
    second from numba's cache) the caller should do before the clock starts."""
    phases: bool = False
    """Whether the method solves a document with ``phases`` (linked legs, each with its own
    duration, end conditions and bounds); without it the registry refuses such a document."""
    propulsion: bool = False
    """Whether the method flies a vehicle with ``propulsion`` (thrust, mass flow, thrust lag);
    without it the registry refuses such a document."""

    def describe(self) -> dict[str, Any]:
        """JSON-ready description with the default options of the method."""
        return {
            "name": self.name,
            "title": self.title,
            "paper": self.paper,
            "features": list(self.features),
            "objectives": list(self.objectives),
            "phases": self.phases,
            "propulsion": self.propulsion,
            "default_options": self.options_type.model_validate({}).model_dump(mode="json"),
        }


def issue(field: str, message: str, code: str = "unsupported_by_method") -> FieldIssue:
    """A field issue (``unsupported_by_method`` unless another code is given)."""
    return FieldIssue(field=field, message=message, code=code)


def scheduled_alpha_issues(doc: ProblemDocument, name: str) -> list[FieldIssue]:
    """Refusals shared by methods that fly a scheduled angle of attack with CL(alpha), CD(alpha)."""
    out = []
    attack = doc.vehicle.angle_of_attack
    if attack is not None and attack.mode == "optimized":
        out.append(
            issue(
                "vehicle.angle_of_attack",
                f"{name} flies a scheduled angle of attack; "
                "give a velocity_schedule, table or constant",
            )
        )
    out += polar_issues(doc, name)
    if doc.control_limits.alpha_rate_max_deg_s is not None:
        out.append(
            issue(
                "control_limits.alpha_rate_max_deg_s",
                f"{name} does not optimize the angle of attack",
            )
        )
    return out


def polar_issues(doc: ProblemDocument, name: str) -> list[FieldIssue]:
    """Refusal of a normalized-lift polar by a method that flies CL and CD of alpha."""
    if doc.vehicle.aerodynamics.model != "parabolic_polar":
        return []
    return [issue("vehicle.aerodynamics", f"{name} needs CL and CD as functions of angle of "
                  "attack (polynomial or table), not a normalized-lift polar")]  # fmt: skip


def spherical_only_issues(doc: ProblemDocument, name: str) -> list[FieldIssue]:
    """Refusal of paper 001's flat-Earth model by a method built on the spherical equations."""
    if doc.planet.model == "spherical":
        return []
    return [issue("planet.model", f"{name} flies the spherical planet model; only cheb-scvx "
                  "flies the flat-Earth model")]  # fmt: skip


def objective_issues(
    doc: ProblemDocument, name: str, supported: Sequence[str], verb: str
) -> list[FieldIssue]:
    """Objective terms the method cannot ``verb`` (minimize, optimize), and a heat load
    objective without its heating model."""
    out = []
    for i, term in enumerate(doc.objective.terms):
        if term.name not in supported:
            out.append(
                issue(
                    f"objective.terms[{i}].name",
                    f"{name} cannot {verb} {term.name!r}; it supports {', '.join(supported)}",
                )
            )
        if term.name == "min_heat_load" and doc.path_constraints.heat_rate is None:
            out.append(
                issue(
                    "path_constraints.heat_rate",
                    "min_heat_load needs the heating "
                    "model (k_q and exponents) in path_constraints.heat_rate",
                )
            )
    return out
