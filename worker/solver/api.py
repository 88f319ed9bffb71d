"""Public entry point of the solver core: one problem document in, one result document out.

Data flow: request schema -> problem model (problem.build_problem) -> method (transcription +
SCP loop + conic backend) -> verification by propagation -> result document.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, cast

import numpy as np

from app.schemas import ProblemDocument
from app.schemas.methods import AutoOptions
from app.schemas.plausibility import plausibility_warnings
from app.schemas.result import json_ready
from worker.solver.auto import solve_auto
from worker.solver.auto.named import with_second_start
from worker.solver.diagnosis import BUDGET_CODES, advice, blame_input, input_advice, stall_note
from worker.solver.failure_causes import name_causes, refusal
from worker.solver.finite import non_finite_entries
from worker.solver.global_start import GlobalStartStoppedError, with_global_start
from worker.solver.methods import METHODS, check_support
from worker.solver.models.bank_state_compiled import compiled_parameters
from worker.solver.objective_weights import weighted_sum
from worker.solver.objectives import UNITS
from worker.solver.phased_problem import PhasedProblem, build_phased_problem
from worker.solver.problem import EntryProblem, build_problem
from worker.solver.result import (
    input_provenance,
    node_violations,
    phased_node_violations,
    phased_trajectory_columns,
    provenance,
    trajectory_columns,
    validated,
)
from worker.solver.scp.history import IterationRecord
from worker.solver.trajectory import OptimizedTrajectory, PhasedTrajectory
from worker.solver.verification import VerificationStoppedError, verify
from worker.solver.verification_phased import verify_phased
from worker.solver.warmup import KernelWait, warm_up

IterationCallback = Callable[[dict[str, Any]], None]
StopCheck = Callable[[], bool]
PhaseCallback = Callable[[str], None]
"""Told ``"optimizing"`` when the SCP iterations start and ``"verifying"`` when the propagation
of the answer starts."""

_STATUS = {
    "converged": "succeeded",
    "max_iterations": "failed",
    "failed": "failed",
    "cancelled": "cancelled",
    "timed_out": "timed_out",
}


def _verification_failures(report: dict[str, Any]) -> list[str]:
    reasons = []
    if not report["reached_end"]:
        reasons.append("the propagated trajectory did not reach the end of the optimized one")
    for name, entry in report["terminal_error_vs_target"].items():
        if entry["kind"] in ("fixed", "range") and not entry["within"]:
            reasons.append(
                f"terminal {name} off by {entry['error']:.4g} (tolerance {entry['tolerance']:g})"
            )
    for name, entry in report["path_maxima"].items():
        if "within" in entry and not entry["within"]:
            where = f" (phase {entry['phase']})" if entry.get("phase") else ""
            reasons.append(f"{name} peaks at {entry['ratio']:.4f} of its limit{where}")
    for zone in report["no_fly_zones"]:
        if not zone["within"]:
            reasons.append(
                f"no-fly zone {zone['name'] or ''} entered by {-zone['min_clearance_deg']:.4f} deg"
            )
    for name, entry in report.get("control_limits", {}).items():
        if not entry["within"]:
            reasons.append(
                f"the flown {name} reaches {entry['max']:.4g} at t = {entry['at_time_s']:.1f} s "
                f"({entry['ratio']:.4f} of its limit {entry['limit']:g})"
            )
    for phase in report.get("phases", [])[:-1]:  # the last phase's end is the terminal above
        for name, entry in phase["end_error_vs_target"].items():
            if entry["kind"] in ("fixed", "range") and not entry["within"]:
                reasons.append(
                    f"phase {phase['name']} ends with {name} off by {entry['error']:.4g} "
                    f"(tolerance {entry['tolerance']:g})"
                )
    if not report["feasible"] and not reasons:  # no check may fail unnamed
        reasons.append("the verification found the trajectory infeasible")
    return reasons


def _objective(
    terms: dict[str, float], report: dict[str, Any] | None, weights: dict[str, float]
) -> dict[str, Any]:
    """The result's objective entry: the method's terms (and their weighted sum when there are
    several), and the propagated heat load when the objective is the heat load and the
    verification ran."""
    single = len(terms) == 1
    name = next(iter(terms)) if single else "weighted_sum"
    propagated = (
        report["heat_load_J_m2"] if report is not None and name == "min_heat_load" else None
    )
    return {
        "name": name,
        "value": next(iter(terms.values())) if single else weighted_sum(terms, weights),
        "units": UNITS.get(name, "mixed"),
        "propagated_value": propagated,
        "terms": terms,
    }


def _fail(document: dict[str, Any], code: str, message: str) -> None:
    """Turn ``document`` into a failed result with ``code`` and ``message``."""
    document["status"] = "failed"
    document["failure"] = {"code": code, "message": message}


def _broken_code(code: str | None) -> str:
    """The failure code of a result whose numbers are not finite: the driver's own when it
    names a breakdown, else numerical_error."""
    return code if code in ("diverged", "numerical_error") else "numerical_error"


def _time_runs_backwards(columns: dict[str, Any]) -> str | None:
    """Why the trajectory's clock is no flight's (a node's time before its predecessor's, or
    no time after the start), for the failure message; None for an increasing clock. Such a
    last iterate (an energy-grid method's time integral gone negative) cannot be flown, so it
    is not verified."""
    t = np.asarray(columns.get("time_s") or [], dtype=float)
    if t.size < 2:
        return None
    steps = np.diff(t)
    if np.all(steps >= 0.0) and t[-1] > t[0]:
        return None
    k = int(np.argmin(steps)) + 1
    return (
        f"the last iterate's clock runs backwards (node {k} at t = {t[k]:.1f} s after "
        f"{t[k - 1]:.1f} s; the flight ends at {t[-1]:.1f} s): not a flight, so it was not "
        "verified; the iterates diverged (try another method, or a start near the answer)"
    )


def _broken_message(failure: dict[str, str] | None, where: list[str]) -> str:
    """What is non-finite, after the driver's message; the verification was skipped."""
    lead = f"{failure['message']}; " if failure and failure["message"] else ""
    shown = ", ".join(where[:6]) + (f" and {len(where) - 6} more" if len(where) > 6 else "")
    return (
        f"{lead}the last iterate holds non-finite values ({shown}); no trajectory is reported "
        "and the verification was skipped"
    )


NOT_VERIFIED = "the trajectory is the last iterate and was not verified"


def _stopped(document: dict[str, Any], where: str) -> None:
    """Turn ``document`` into a cancelled result that says ``where`` the stop came."""
    _fail(document, "cancelled", f"stopped {where}; {NOT_VERIFIED}")
    document["status"] = "cancelled"


def stopped_in_optimization(iterations: int) -> str:
    """Where a stop asked for during the optimization came, in the history's numbering
    (``iterations`` records were complete)."""
    return f"during the optimization, before iteration {iterations + 1}"


def _judge(
    document: dict[str, Any],
    report: dict[str, Any] | None,
    violations: list[str],
    driver_message: str | None,
) -> None:
    """The honest status of a result with a finite trajectory: cancelled when the verification
    was stopped; ``infeasible`` (which constraint, where, by how much) when the run converged
    or used its budget with constraints unmet at the nodes; ``verification_failed`` when it
    converged and the propagated controls violate; a failed verification of a failed result
    is named in its message; non-finite verification numbers fail the result."""
    if report is None:
        _stopped(document, "during the verification")
        return
    broken = non_finite_entries(report, "verification")
    if broken:
        _fail(
            document,
            "numerical_error",
            "the propagation of the controls gave non-finite values ("
            + ", ".join(broken[:6])
            + ")",
        )
        return
    reasons = _verification_failures(report) if not report["feasible"] else []
    if violations:
        lead = driver_message or "converged"
        tail = f"; the propagated controls violate: {'; '.join(reasons)}" if reasons else ""
        _fail(document, "infeasible", f"{lead}, infeasible: {'; '.join(violations)}{tail}")
    elif document["status"] == "succeeded" and reasons:
        _fail(
            document,
            "verification_failed",
            "converged, but the propagated controls violate: " + "; ".join(reasons),
        )
    elif document["status"] == "succeeded":
        missed = _objective_miss(document.get("objective"), report)
        if missed is not None:
            _fail(document, "verification_failed", f"converged, but {missed}")


def _objective_miss(objective: dict[str, Any] | None, report: dict[str, Any]) -> str | None:
    """Why the flown objective does not confirm the optimized one: a heat load flown more than
    ``objective_relative`` above the value the optimizer reports (its quadrature missed heating
    between the nodes); None when it confirms or there is nothing to compare."""
    if not objective or objective.get("propagated_value") is None:
        return None
    value, flown = objective["value"], objective["propagated_value"]
    tolerance = report["tolerances"]["objective_relative"]
    if value is None or flown <= value + tolerance * abs(value):
        return None
    return (
        f"the flown heat load {flown:.6g} J/m^2 is {100 * (flown / value - 1):.2f} % above the "
        f"optimized {value:.6g} (tolerance {100 * tolerance:g} %): the optimizer's quadrature "
        "misses heating between its nodes; raise method.nodes or try another method"
    )


PHASED_DYNAMICS_NOTE = (
    "the powered dynamics of a flight in phases (thrust and mass) have no compiled form; numpy code"
)


def _columns(
    model: EntryProblem | PhasedProblem, traj: OptimizedTrajectory | PhasedTrajectory
) -> dict[str, Any]:
    """The trajectory's columns, of a flight in phases or of one phase."""
    if isinstance(model, PhasedProblem):
        return phased_trajectory_columns(model, cast(PhasedTrajectory, traj))
    return trajectory_columns(model, cast(OptimizedTrajectory, traj))


def _verify(
    model: EntryProblem | PhasedProblem,
    traj: OptimizedTrajectory | PhasedTrajectory,
    should_stop: StopCheck | None,
) -> dict[str, Any]:
    """The verification report, of a flight in phases or of one phase."""
    if isinstance(model, PhasedProblem):
        return verify_phased(model, cast(PhasedTrajectory, traj), should_stop=should_stop)
    return verify(model, cast(OptimizedTrajectory, traj), should_stop=should_stop)


def _violations(
    model: EntryProblem | PhasedProblem,
    traj: OptimizedTrajectory | PhasedTrajectory,
    last: IterationRecord | None,
) -> list[str]:
    """What the nodes do not meet, of a flight in phases or of one phase."""
    if isinstance(model, PhasedProblem):
        return phased_node_violations(model, cast(PhasedTrajectory, traj))
    return node_violations(model, cast(OptimizedTrajectory, traj), last)


def solve_problem(
    problem: ProblemDocument,
    *,
    on_iteration: IterationCallback | None = None,
    should_stop: StopCheck | None = None,
    on_phase: PhaseCallback | None = None,
    on_kernels: Callable[[KernelWait], None] | None = None,
    prechecks: bool = True,
) -> dict[str, Any]:
    """Solve ``problem`` with its selected method and return the JSON-ready result document.

    ``on_iteration`` receives each per-iteration history record as soon as it exists;
    ``should_stop`` is polled once per SCP iteration and every fraction of a second during the
    verification (a true answer ends the solve as ``cancelled`` with the history so far);
    ``on_phase`` hears when optimization and verification start; ``on_kernels`` hears why the
    optimization waits for the method's compiled kernels (``warmup.warm_up``): "compiling" when
    numba's cache lacks them (once after an install), "loading" when a load from the cache is
    slow. ``prechecks``: run the physical pre-checks (``prechecks``; a proof of infeasibility
    ends the solve before the method, a failure names its likely cause); False runs the method
    on any problem and reports its failure in the method's own terms (tests of that reporting).
    A stop during the optimization ends it before the next iteration and starts no
    verification; the failure message says whether the optimization (before which iteration)
    or the verification was stopped. Solver failures
    (infeasible, diverged, time limit, numerical trouble, failed verification) come back as a
    result with ``status`` ``failed`` or ``timed_out`` and a ``failure`` {code, message}; only
    programming errors raise. A problem whose method is ``auto`` is solved by the methods that
    accept it in auto's order (``worker.solver.auto``), each attempt a solve of this function;
    a named method's success in a class with separate local optima is followed by a second
    start of the same method (``auto.named``; ``method.second_start``).
    """
    hooks: dict[str, Any] = {
        "on_iteration": on_iteration,
        "should_stop": should_stop,
        "on_phase": on_phase,
        "on_kernels": on_kernels,
    }
    if isinstance(problem.method, AutoOptions):
        return solve_auto(problem, solve_problem, **hooks)
    cpu_start = time.process_time()
    first = _solve_named(problem, **hooks, prechecks=prechecks)
    return with_second_start(problem, first, solve_problem, hooks, cpu_start)


def _solve_named(
    problem: ProblemDocument,
    *,
    on_iteration: IterationCallback | None,
    should_stop: StopCheck | None,
    on_phase: PhaseCallback | None,
    on_kernels: Callable[[KernelWait], None] | None,
    prechecks: bool,
) -> dict[str, Any]:
    """One run of the document's named method: its optimization, verification and advice
    (``solve_problem`` without the second start)."""
    start = time.perf_counter()
    cpu_start = time.process_time()
    method = problem.method.name
    about_input: dict[str, Any] = {  # what every result says of its input, a solve or not
        "provenance": input_provenance(problem),
        "warnings": [w.model_dump() for w in plausibility_warnings(problem)],
    }
    issues = check_support(problem)
    if issues:
        message = "; ".join(f"{i.field}: {i.message}" for i in issues)
        return validated(
            {
                "status": "failed",
                "method": method,
                "failure": {"code": "unsupported_by_method", "message": message},
                "timing": {"wall_s": 0.0, "conic_solve_s": 0.0, "iterations": 0},
                **about_input,
            }
        )
    # a method that flies phases gets the phased model (one phase when the document gives none)
    phased = METHODS[method].phases
    model: EntryProblem | PhasedProblem = (
        build_phased_problem(problem) if phased else build_problem(problem)
    )
    base = model.base if isinstance(model, PhasedProblem) else model
    # a flight in phases or with an engine is not what the pre-checks' gliding flights describe
    prechecked = prechecks and not problem.phases and problem.vehicle.propulsion is None
    refused, pull_up = refusal(base) if prechecked else (None, None)
    if refused is not None:
        refused["advice"] = [*input_advice(about_input), *refused["advice"]]
        return validated(
            {
                "status": "failed",
                "method": method,
                "failure": refused,
                "history": [],
                "timing": {
                    "wall_s": 0.0,
                    "conic_solve_s": 0.0,
                    "iterations": 0,
                    "total_s": time.perf_counter() - start,
                    "cpu_s": time.process_time() - cpu_start,
                },
                **about_input,
            }
        )
    options = problem.method
    assert not isinstance(options, AutoOptions)  # auto is solved by its attempts
    start_note: str | None = None
    guess = problem.initial_guess
    if isinstance(model, EntryProblem) and guess is not None and guess.kind == "global":
        try:
            model, start_note = with_global_start(
                problem, model, should_stop=should_stop, job_time_limit_s=options.time_limit_s
            )
        except GlobalStartStoppedError:
            return validated(
                {
                    "status": "cancelled",
                    "method": method,
                    "failure": {
                        "code": "cancelled",
                        "message": "cancelled during the global search for a start",
                    },
                    "timing": {"wall_s": 0.0, "conic_solve_s": 0.0, "iterations": 0},
                    **about_input,
                }
            )
        base = model
        # the method has what the search left of the job's CPU time limit (at least half of it)
        spent = time.process_time() - cpu_start
        options = options.model_copy(update={"time_limit_s": options.time_limit_s - spent})
    streamed: list[IterationRecord] = []

    def forward(record: IterationRecord) -> None:
        streamed.append(record)
        if on_iteration is not None:
            on_iteration(json_ready(record.as_dict()))

    if (
        not phased
        and METHODS[method].warm_kernels
        and compiled_parameters(base.forces, base.omega) is not None
    ):
        # loaded (or compiled) before the clock: wall_s is the optimization's own
        warm_up(on_kernels)
    if on_phase is not None:
        on_phase("optimizing")
    scp_start = time.perf_counter()
    # a non-physical iterate's NaN or overflow is found and reported in the result (diverged,
    # numerical_error with where), not printed as a numpy warning on the caller's stderr
    with np.errstate(all="ignore"):
        # the runner hands the model on as it is: a phased method's run takes the phased one
        outcome = METHODS[method].run(cast(Any, model), options, forward, should_stop)
    wall = time.perf_counter() - scp_start - outcome.verification_s  # the optimization's own
    status = _STATUS[outcome.status]
    failure = (
        {"code": outcome.failure_code or "failed", "message": outcome.failure_message or ""}
        if status != "succeeded"
        else None
    )
    history = outcome.history
    # the diverging record is streamed, not judged (a multi-start run keeps it in its history)
    if outcome.failure_code == "diverged" and outcome.starts is None:
        history = history + streamed[len(history) :]
    document: dict[str, Any] = {
        "status": status,
        "failure": failure,
        "method": method,
        "history": [r.as_dict() for r in history],
        "provenance": provenance(base, about_input["provenance"]),
        "warnings": about_input["warnings"],
    }
    if phased:
        document["provenance"].update(dynamics="numpy", dynamics_note=PHASED_DYNAMICS_NOTE)
    if start_note is not None:
        document["provenance"]["initial_guess"] = start_note
    if outcome.starts is not None:
        document["starts"] = outcome.starts
    verification_s = 0.0
    if outcome.trajectory is not None:
        traj = outcome.trajectory
        columns = _columns(model, traj)
        weights = {term.name: term.weight for term in base.objective}
        document["objective"] = _objective(outcome.objective_terms, None, weights)
        broken = non_finite_entries({"trajectory": columns, "objective": document["objective"]})
        backwards = _time_runs_backwards(columns)
        if broken:
            _fail(document, _broken_code(outcome.failure_code), _broken_message(failure, broken))
        elif backwards is not None:
            document["trajectory"] = columns
            document["verification"] = None
            lead = f"{failure['message']}; " if failure and failure["message"] else ""
            _fail(document, _broken_code(outcome.failure_code), f"{lead}{backwards}")
        elif outcome.status == "cancelled":
            # stopped during the optimization: the stop still holds, so nothing is verified
            document["trajectory"] = columns
            document["verification"] = None
            _stopped(document, stopped_in_optimization(len(history)))
        else:
            document["trajectory"] = columns
            if on_phase is not None:
                on_phase("verifying")
            v_start = time.perf_counter()
            report: dict[str, Any] | None = outcome.verification
            if report is None:
                try:
                    report = _verify(model, traj, should_stop)
                except VerificationStoppedError:
                    report = None
            verification_s = time.perf_counter() - v_start + outcome.verification_s
            document["verification"] = report
            document["objective"] = _objective(outcome.objective_terms, report, weights)
            last = outcome.last_record
            violations = (
                _violations(model, traj, last)
                if outcome.status in ("converged", "max_iterations")
                else []
            )
            _judge(document, report, violations, outcome.failure_message)
    causes = name_causes(document, base, pull_up, problem) if prechecked else []
    last_record = outcome.last_record
    explain(document, problem.method, last_record.as_dict() if last_record else None, causes)
    document["timing"] = {
        "wall_s": wall,
        "conic_solve_s": outcome.conic_solve_s,
        "iterations": len(history),
        "verification_s": verification_s,
        "total_s": time.perf_counter() - start,
        "cpu_s": time.process_time() - cpu_start,
    }
    return validated(document)


def explain(
    document: dict[str, Any],
    options: Any,
    last: dict[str, Any] | None = None,
    causes: list[str] | None = None,
) -> None:
    """Add to a failed result what was still moving when a budget ran out and what a user can
    change (``failure.advice``): its implausible inputs first, then ``causes`` (the advice of
    the pre-checks' named causes), then the method's; a cancelled one is left as it is.
    ``last``: the last iteration of the run whose answer is reported (default: the history's
    last record; a run of several starts reports one start's answer)."""
    failure = document.get("failure")
    if document["status"] in ("succeeded", "cancelled") or not failure:
        return
    blame_input(failure, document.get("warnings") or [])
    if failure["code"] in BUDGET_CODES:
        history = document["history"]
        note = stall_note(last or (history[-1] if history else None), options)
        if note:
            failure["message"] = f"{failure['message']}; {note}"
    hints = [*input_advice(document), *(causes or []), *advice(document, options)]
    hints = list(dict.fromkeys(hints))
    if hints:
        failure["advice"] = hints
