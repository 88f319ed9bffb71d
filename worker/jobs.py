"""Run one stored job: claim an attempt, solve, record progress per iteration, store the outcome.

``execute_job`` is the single code path of every worker: the Celery task calls it, and so does the
local process pool of the embedded mode. It imports neither FastAPI nor Celery.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pydantic import ValidationError

from app.failure_log import FailureLog
from app.schemas.result import json_ready
from app.settings import Settings, get_settings
from app.storage import repository
from app.storage.models import JobStatus
from app.storage.repository import ClaimState
from app.storage.session import Database, database_unreachable, get_database
from worker.heartbeat import Heartbeat
from worker.limits import TimeLimits, job_time_limits
from worker.watchdog import SolveWatchdog

log = logging.getLogger(__name__)

SolveFn = Callable[..., dict[str, Any]]
NotifyFn = Callable[[str, str], None]
"""``notify(job_id, kind)`` with kind ``"iteration"`` or ``"end"``: wakes up event streams."""


def progress_of(record: dict[str, Any], elapsed_s: float) -> dict[str, Any]:
    """The live-progress summary of one iteration record (with an auto attempt's method)."""
    progress = {
        "phase": "optimizing",
        "iteration": record.get("iteration"),
        "cost": record.get("cost"),
        "max_state_change": record.get("max_state_change"),
        "conic_status": record.get("conic_status"),
        "elapsed_s": round(elapsed_s, 6),
    }
    extra = record.get("extra")
    if isinstance(extra, dict) and extra.get("auto_attempt") is not None:
        progress["method"] = extra.get("method")
    return progress


@dataclass
class _Attempt:
    """State of one running attempt, shared by the solver callbacks."""

    job_id: str
    attempt: int
    database: Database
    limits: TimeLimits
    notify: NotifyFn | None
    passthrough: tuple[type[BaseException], ...] = ()
    lease_s: float = 30.0
    heartbeat: Heartbeat | None = None
    started: float = field(default_factory=time.monotonic)
    cpu_started: float = field(default_factory=time.process_time)
    history: list[dict[str, Any]] = field(default_factory=list)
    deadline_hit: str | None = None
    """Which of the job's time limits stopped the solve ("CPU time limit of 120 s", ...)."""
    stop_requested: bool = False
    write_errors: int = 0
    stored: int | None = 0
    """Iterations the stored history holds, as this attempt's last write left it (``None``
    after a write that failed: it may or may not have been committed)."""
    origin: dict[str, Any] | None = None
    """A scenario job's scenario and patches, for its result's provenance."""
    failures: FailureLog = field(init=False)
    """The attempt's failed database writes and reads, logged with back-off."""

    def __post_init__(self) -> None:
        self.failures = FailureLog(log, f"job {self.job_id}")

    def elapsed(self) -> float:
        return time.monotonic() - self.started

    def cpu_used(self) -> float:
        """CPU seconds this process spent since the attempt's clock started (the solve runs
        in it, every thread of it counted)."""
        return time.process_time() - self.cpu_started

    def _write(self, what: str, kind: str, write: Callable[[Any], bool]) -> bool:
        """Run one progress ``write`` (True while the attempt owns the job), then wake the
        job's event streams with ``kind``; a lost write is logged, it must not kill the solve.
        Each write is one fenced statement or two: no transaction around them. True if the
        write was made."""
        try:
            with self.database.autocommit() as session:
                owned = write(session)
            if not owned:
                self.stop_requested = True
        except self.passthrough:
            raise
        except Exception as exc:
            self.write_errors += 1
            self.failures.failed(exc, f"store {what}", "the solve goes on")
            return False
        self.failures.succeeded("the database answers again")
        if self.notify is not None:
            self.notify(self.job_id, kind)
        return owned

    def on_iteration(self, record: Any) -> None:
        """Append the new iteration to the stored history (with any an earlier lost write
        missed) and store its live progress."""
        clean = json_ready(record)
        if not isinstance(clean, dict):
            clean = {"record": clean}
        self.history.append(clean)
        history, progress = list(self.history), progress_of(clean, self.elapsed())
        stored, self.stored = self.stored, None  # unknown until the write is known made
        made = self._write(
            "iteration progress",
            "iteration",
            lambda session: repository.record_iteration(
                session, self.job_id, self.attempt, history, progress, self.lease_s, stored
            ),
        )
        if made:
            self.stored = len(history)

    def on_phase(self, phase: str) -> None:
        """Store that the attempt entered ``phase`` (loading, compiling, optimizing, verifying),
        keeping the last iteration's figures, and wake the job's event streams."""
        last = progress_of(self.history[-1], self.elapsed()) if self.history else {"iteration": 0}
        progress = {**last, "phase": phase, "elapsed_s": round(self.elapsed(), 6)}
        self._write(
            f"its phase {phase}",
            "progress",
            lambda session: repository.record_progress(
                session, self.job_id, self.attempt, progress, self.lease_s
            ),
        )

    def should_stop(self) -> bool:
        limits = self.limits
        if limits.cpu_s is not None and self.cpu_used() > limits.cpu_s:
            self.deadline_hit = f"CPU time limit of {limits.cpu_s:g} s"
            return True
        if self.elapsed() > limits.solve_s:
            self.deadline_hit = f"wall-clock limit of {limits.solve_s:g} s"
            return True
        if self.stop_requested or (self.heartbeat is not None and self.heartbeat.lost):
            self.stop_requested = True
            return True
        try:
            with self.database.reader() as session:
                self.stop_requested = repository.should_stop(session, self.job_id, self.attempt)
        except self.passthrough:
            raise
        except Exception as exc:
            self.failures.failed(exc, "read the cancel flag", "the solve goes on")
        return self.stop_requested


@dataclass(frozen=True)
class Outcome:
    """What is stored when an attempt ends."""

    status: str
    result: dict[str, Any] | None
    history: list[dict[str, Any]]
    error_code: str | None
    error_message: str | None
    solve_s: float | None


def _outcome_from_result(result: dict[str, Any], attempt: _Attempt) -> Outcome:
    result = json_ready(result)
    history = result.get("history")
    if not isinstance(history, list):
        history = list(attempt.history)
    status = str(result.get("status"))
    failure = result.get("failure") if isinstance(result.get("failure"), dict) else None
    if status == JobStatus.CANCELLED and attempt.deadline_hit and not attempt.stop_requested:
        status = JobStatus.TIMED_OUT.value
        message = f"stopped at the job's {attempt.deadline_hit}"
        stopped = str((failure or {}).get("message") or "")
        if stopped.startswith("stopped "):  # the solver's "stopped during ...": where it was
            message += ", " + stopped.removeprefix("stopped ")
        failure = {"code": "time_limit", "message": message}
        result["status"], result["failure"] = status, failure
    elif status == JobStatus.CANCELLED:
        failure = failure or {"code": "cancelled", "message": "cancelled on request"}
    if status not in {s.value for s in JobStatus} or status in (JobStatus.QUEUED, "running"):
        return Outcome(
            JobStatus.FAILED.value,
            result,
            history,
            "internal_error",
            f"the solver returned an unknown status {status!r}",
            None,
        )
    timing = result.get("timing") if isinstance(result.get("timing"), dict) else {}
    wall = timing.get("total_s", timing.get("wall_s")) if timing else None
    solve_s = float(wall) if isinstance(wall, int | float) else attempt.elapsed()
    return Outcome(
        status=status,
        result=result,
        history=history,
        error_code=str(failure.get("code")) if failure else None,
        error_message=str(failure.get("message")) if failure else None,
        solve_s=solve_s,
    )


def _default_solve() -> SolveFn:
    from worker.solver.api import solve_problem

    return solve_problem


def _cancelled_after_the_solve(outcome: Outcome) -> Outcome:
    """``outcome`` turned into ``cancelled``: the cancel was accepted before it was stored, so the
    job ends as the client was told (202), with the finished result kept for the record."""
    message = f"cancelled on request after the solve had ended {outcome.status}; its result is kept"
    result = dict(outcome.result) if outcome.result is not None else None
    if result is not None:
        result["status"] = JobStatus.CANCELLED.value
        result["failure"] = {"code": "cancelled", "message": message}
    return dataclasses.replace(
        outcome,
        status=JobStatus.CANCELLED.value,
        result=result,
        error_code="cancelled",
        error_message=message,
    )


def _finish(attempt: _Attempt, outcome: Outcome) -> str | None:
    """Store the outcome if this attempt still owns the job; a cancel accepted meanwhile wins.

    The write of any outcome but ``cancelled`` requires that no cancel was requested, and the
    cancel request requires a job still active: the two conditional updates serialize, so a
    DELETE answered 202 always ends the job ``cancelled``. Returns the status stored, or
    ``None`` when the attempt no longer owns the job.
    """
    with attempt.database.autocommit() as session:  # each write is one fenced statement
        if _store(session, attempt, outcome):
            return outcome.status
        if outcome.status == JobStatus.CANCELLED:
            return None
        cancelled = _cancelled_after_the_solve(outcome)
        return cancelled.status if _store(session, attempt, cancelled) else None


def _finish_despite_outages(attempt: _Attempt, outcome: Outcome, hold_until: float) -> str | None:
    """:func:`_finish`, retried while the database is unreachable, until the monotonic instant
    ``hold_until``: a finished result is kept in this process and written when the database
    returns. Retries back off from 0.5 to 5 s; the log gets one line per streak and then lines
    at growing intervals (:class:`FailureLog`)."""
    pause = 0.5
    while True:
        try:
            stored = _finish(attempt, outcome)
        except Exception as exc:
            if not database_unreachable(exc) or time.monotonic() + pause > hold_until:
                raise
            attempt.failures.failed(
                exc,
                f"store its {outcome.status} outcome",
                f"the database is unreachable; keeping the {outcome.status} result and "
                f"retrying for up to {max(0.0, hold_until - time.monotonic()):.0f} s",
            )
            time.sleep(pause)
            pause = min(2.0 * pause, 5.0)
            continue
        attempt.failures.succeeded("the database answers again")
        return stored


def _store(session: Any, attempt: _Attempt, outcome: Outcome) -> bool:
    """Complete the stored history with what its lost writes missed, then store the outcome
    (the result's own history is the stored one: it is kept once).

    When the attempt knows how many records are stored (its writes all went through) both
    are one statement; otherwise, or when that one does not apply, two steps tell the cases
    apart (a lost write, a job no longer owned, a cancel requested).
    """
    allowed_from = [JobStatus.RUNNING.value, JobStatus.QUEUED.value]
    # queued too: the sweeper may have re-queued the job while the database was away
    # and no other attempt has claimed it yet, so this finished result is still the job's
    last = outcome.history[-1] if outcome.history else None
    values: dict[str, Any] = {
        "result": repository.result_for_storage(outcome.result),
        "error_code": outcome.error_code,
        "error_message": outcome.error_message,
        "solve_s": outcome.solve_s,
    }
    elapsed = attempt.elapsed()
    progress: dict[str, Any] = progress_of(last, elapsed) if last is not None else {"iteration": 0}
    if outcome.result is not None and outcome.result.get("attempts") is not None:
        progress["method"] = outcome.result.get("method")  # auto's kept answer's method
    values["progress"] = {**progress, "phase": "finished", "elapsed_s": round(elapsed, 6)}
    unless_cancel_requested = outcome.status != JobStatus.CANCELLED
    if (
        attempt.stored is not None
        and attempt.stored <= len(outcome.history)
        and repository.store_outcome(
            session,
            attempt.job_id,
            attempt=attempt.attempt,
            history=outcome.history,
            stored=attempt.stored,
            to=outcome.status,
            allowed_from=allowed_from,
            values=values,
            unless_cancel_requested=unless_cancel_requested,
        )
    ):
        return True
    if not repository.complete_history(
        session, attempt.job_id, attempt.attempt, outcome.history, allowed_from
    ):
        return False
    attempt.stored = len(outcome.history)
    return repository.transition(
        session,
        attempt.job_id,
        to=outcome.status,
        allowed_from=allowed_from,
        attempt=attempt.attempt,
        values=values,
        unless_cancel_requested=unless_cancel_requested,
    )


def _chained(database: Any, claim: Any, problem_raw: dict[str, Any]) -> dict[str, Any]:
    """The problem of a chained batch's child, started from its nearest finished sibling; as
    stored when that cannot be read (the child then starts from the method's own guess)."""
    from app.schemas import ProblemDocument
    from worker.chaining import with_sibling_guess
    from worker.solver.methods import check_support

    try:
        chained = with_sibling_guess(
            database, claim.batch_id, claim.batch_parameters or {}, problem_raw
        )
        if chained is not problem_raw and check_support(ProblemDocument.model_validate(chained)):
            return problem_raw  # the child's method takes no initial guess
        return chained
    except Exception:
        log.warning("job's sibling guess could not be read; it starts cold", exc_info=True)
        return problem_raw


def _origin(claim: Any) -> dict[str, Any] | None:
    """A scenario job's scenario and the patches it was submitted with (None for a problem
    document, or a job stored before its patches were)."""
    if claim.scenario is None or claim.overrides is None:
        return None
    patches = claim.overrides
    return {
        "name": claim.scenario,
        "overrides": patches.get("overrides") or {},
        "method": patches.get("method"),
    }


def _solved(attempt: _Attempt, problem_raw: dict[str, Any]) -> dict[str, Any]:
    """``problem_raw`` (a chained child's problem with its sibling's start) normalized and
    stored as the problem the job solves, so GET /problem and the result's fingerprint agree."""
    from app.schemas import ProblemDocument

    document: dict[str, Any] = ProblemDocument.model_validate(problem_raw).model_dump(mode="json")
    try:
        with attempt.database.autocommit() as session:
            repository.record_solved_problem(session, attempt.job_id, attempt.attempt, document)
    except Exception:
        log.warning("job %s: could not store the problem it solves", attempt.job_id, exc_info=True)
    return document


def execute_job(
    job_id: str,
    *,
    settings: Settings | None = None,
    solve: SolveFn | None = None,
    timeout_exceptions: tuple[type[BaseException], ...] = (),
    notify: NotifyFn | None = None,
    kill_stuck_solve: bool = False,
) -> str:
    """Run job ``job_id`` once and return its final status (or why it did not run).

    Safe to call for any delivery: a finished or unknown job is left alone, the attempt counter
    is incremented atomically, and after ``max_attempts`` the job ends ``failed``/``worker_lost``.
    ``timeout_exceptions`` are raised into the solve by a supervisor's soft time limit; they end
    the job as ``timed_out`` with the history collected so far. With ``kill_stuck_solve`` (a
    Celery pool process) a solve still running at the job's ``stuck_s`` ends the process.
    """
    settings = settings or get_settings()
    database = get_database(settings.effective_database_url)
    with database.autocommit() as session:  # one conditional UPDATE ... RETURNING
        claim = repository.claim_attempt(session, job_id, settings.max_attempts, settings.lease_s)
    problem_raw = claim.problem
    if claim.state is not ClaimState.CLAIMED or problem_raw is None:
        log.info("job %s not run: %s (attempts %d)", job_id, claim.state.value, claim.attempt)
        if notify is not None and claim.state in (ClaimState.EXHAUSTED, ClaimState.CANCELLED):
            notify(job_id, "end")
        return claim.state.value

    attempt = _Attempt(
        job_id=job_id,
        attempt=claim.attempt,
        database=database,
        limits=job_time_limits(problem_raw, settings),
        notify=notify,
        passthrough=timeout_exceptions,
        lease_s=settings.lease_s,
        origin=_origin(claim),
    )
    if claim.batch_id is not None:
        chained = _chained(database, claim, problem_raw)
        problem_raw = problem_raw if chained is problem_raw else _solved(attempt, chained)
    log.info("job %s: attempt %d started", job_id, claim.attempt)
    attempt.heartbeat = Heartbeat(database, job_id, claim.attempt, settings.lease_s)
    attempt.heartbeat.start()
    watchdog = SolveWatchdog(attempt.limits.stuck_s if kill_stuck_solve else 0.0)
    try:
        watchdog.arm()
        try:
            if solve is None:  # the real solver: its kernels first (a stand-in needs none)
                _load_solver(attempt)
            outcome = _solve(attempt, problem_raw, solve or _default_solve(), timeout_exceptions)
        finally:
            watchdog.disarm()
        # the hold of the finished result is inside the hard limit (worker.limits), not the
        # watchdog's: a short job keeps its result through the whole hold
        hold_until = time.monotonic() + settings.result_write_retry_s
        try:
            stored = _finish_despite_outages(attempt, outcome, hold_until)
        except timeout_exceptions:  # a soft limit fires once: the second write is not interrupted
            watchdog.disarm()
            stored = _finish_despite_outages(attempt, outcome, hold_until)
    finally:
        watchdog.disarm()
        attempt.heartbeat.stop(wait=False)
    if notify is not None:  # first: the streams' end waits for nothing else
        notify(job_id, "end")
    attempt.heartbeat.join()
    if stored:
        log.info("job %s: attempt %d stored outcome %s", job_id, attempt.attempt, stored)
    else:
        log.warning("job %s: attempt %d no longer owns the job", job_id, attempt.attempt)
    return stored or outcome.status


def _load_solver(attempt: _Attempt) -> None:
    """Load the solver's compiled kernels if this process has not yet: the job's progress says
    ``loading`` (from numba's cache) or ``compiling`` (the first load after an install, which
    takes ``worker.solver.FIRST_COMPILE``). The job's time limit starts after it."""
    from worker.solver import warmup

    if warmup.is_warm():
        return
    attempt.on_phase("loading" if warmup.kernels_cached() else "compiling")
    try:
        seconds = warmup.warm_up()
    except attempt.passthrough:
        raise
    except Exception:  # the solve reports the problem if it needs the kernels
        log.exception("job %s: the solver kernels could not be loaded", attempt.job_id)
        return
    log.info("job %s: solver kernels loaded in %.1f s", attempt.job_id, seconds)
    attempt.started = time.monotonic()
    attempt.cpu_started = time.process_time()


def _solve(
    attempt: _Attempt,
    problem_raw: dict[str, Any],
    solve: SolveFn,
    timeout_exceptions: tuple[type[BaseException], ...],
) -> Outcome:
    from app.schemas import ProblemDocument

    try:
        problem = ProblemDocument.model_validate(problem_raw)
    except ValidationError as exc:
        return Outcome(
            JobStatus.FAILED.value,
            None,
            [],
            "invalid_problem",
            f"the stored problem no longer validates: {exc.error_count()} error(s)",
            None,
        )
    try:
        result = solve(
            problem,
            on_iteration=attempt.on_iteration,
            should_stop=attempt.should_stop,
            on_phase=attempt.on_phase,
        )
    except timeout_exceptions:
        return Outcome(
            JobStatus.TIMED_OUT.value,
            None,
            list(attempt.history),
            "time_limit",
            f"the worker's soft time limit of {attempt.limits.soft_s:g} s was reached",
            attempt.elapsed(),
        )
    except Exception:  # the job says only that it failed; the worker's log has the details
        error_id = f"{time.time_ns():x}"
        log.exception("job %s: the solver raised (error id %s)", attempt.job_id, error_id)
        return Outcome(
            JobStatus.FAILED.value,
            None,
            list(attempt.history),
            "internal_error",
            f"the solver failed unexpectedly (error id {error_id}; the worker's log has the "
            "details)",
            attempt.elapsed(),
        )
    if not isinstance(result, dict):
        return Outcome(
            JobStatus.FAILED.value,
            None,
            list(attempt.history),
            "internal_error",
            "the solver returned no result document",
            attempt.elapsed(),
        )
    if attempt.origin is not None and isinstance(result.get("provenance"), dict):
        result["provenance"]["scenario"] = attempt.origin
    return _outcome_from_result(result, attempt)
