"""The result document of an auto run: the kept attempt's answer (or the most informative
failure's), with every attempt, the combined history and timing, and why auto chose."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

from app.schemas import AutoOptions, ProblemDocument
from app.schemas.plausibility import PlausibilityWarning, plausibility_warnings
from worker.solver.auto.outcome import Attempt, failure_of_none, most_informative
from worker.solver.methods.selection import PREFERENCE, Selection, refusal_issues
from worker.solver.result import input_provenance, validated
from worker.solver.solve_clock import SolveClock


class AutoRun(Protocol):
    """What the document reads of a finished run (``runner.AutoRun``)."""

    @property
    def auto(self) -> AutoOptions: ...
    @property
    def clock(self) -> SolveClock: ...
    @property
    def attempts(self) -> Sequence[Attempt]: ...
    @property
    def history(self) -> Sequence[dict[str, Any]]: ...
    @property
    def stop(self) -> str | None: ...


AUTO_RULE = (
    "the methods whose support checks accept the problem, tried in the order "
    + ", ".join(p.name for p in PREFERENCE)
    + " (docs/problem-contract.md, Method)"
)
"""The rule in one line, for the provenance."""


def _reason(run: AutoRun, selection: Selection, kept: Attempt | None) -> str:
    """Why the kept attempt's method is the result's."""
    names = [c.name for c in selection.candidates]
    accepted = f"the methods that accept the problem, in auto's order: {', '.join(names)}"
    if kept is None:
        return f"{accepted}; none succeeded"
    first = next(c for c in selection.candidates if c.name == run.attempts[0].name)
    if kept.index == 1:
        return f"{accepted}; {kept.name} is the first ({first.reason}) and succeeded"
    failed = [a for a in run.attempts[: kept.index - 1] if a.purpose == "answer"]
    before = ", ".join(f"{a.name} ({a.failure.get('code') or a.status})" for a in failed)
    if kept.purpose == "cross_check":
        return (
            f"{accepted}; the cross-check ({kept.where()}) found a better verified value than "
            "the first answer, and it is kept"
        )
    return f"{accepted}; {before} did not succeed, {kept.name} did"


def _timing(run: AutoRun) -> dict[str, Any]:
    """The whole run's timing: the attempts' optimization, conic and verification times summed."""
    timings = [a.result.get("timing") or {} for a in run.attempts]

    def total(key: str) -> float:
        return float(sum(t.get(key) or 0.0 for t in timings))

    return {
        "wall_s": total("wall_s"),
        "conic_solve_s": total("conic_solve_s"),
        "iterations": len(run.history),
        "verification_s": total("verification_s"),
        "cpu_s": run.clock.cpu_used_s(),
        "total_s": run.clock.wall_used_s(),
    }


def assemble(
    run: AutoRun,
    selection: Selection,
    kept: Attempt | None,
    cross: dict[str, Any] | None,
    about_input: dict[str, Any],
    warnings: list[PlausibilityWarning],
) -> dict[str, Any]:
    """The result document of ``run``: ``kept``'s answer, or the most informative failure's."""
    shown = kept if kept is not None else most_informative(run.attempts)
    document = dict(shown.result)
    if kept is None:
        tried = {a.name for a in run.attempts}
        untried = [c.name for c in selection.candidates if c.name not in tried]
        document["status"] = {"cancelled": "cancelled", "timed_out": "timed_out"}.get(
            run.stop or "", "failed"
        )
        document["failure"] = failure_of_none(
            run.attempts, shown, run.stop, run.auto.time_limit_s, untried
        )
    document["method"] = shown.name
    document["history"] = list(run.history)
    document["attempts"] = [a.summary(a is shown) for a in run.attempts]
    if cross is not None:
        document["cross_check"] = cross
    document["warnings"] = [w.model_dump() for w in warnings]
    document["provenance"] = {
        **(shown.result.get("provenance") or {}),
        **about_input,
        "selection": {
            "chosen": shown.name if kept is not None else None,
            "reason": _reason(run, selection, kept),
            "rule": AUTO_RULE,
            **selection.describe(),
        },
    }
    document["timing"] = _timing(run)
    return document


def refused(problem: ProblemDocument, selection: Selection) -> dict[str, Any]:
    """The failed result of a problem no method accepts (the API refuses it at validation)."""
    issues = refusal_issues(selection)
    return validated(
        {
            "status": "failed",
            "method": "auto",
            "failure": {
                "code": "unsupported_by_method",
                "message": "; ".join(f"{i.field}: {i.message}" for i in issues),
            },
            "attempts": [],
            "timing": {"wall_s": 0.0, "conic_solve_s": 0.0, "iterations": 0},
            "provenance": {
                **input_provenance(problem),
                "selection": {
                    "chosen": None,
                    "reason": "no method accepts the problem",
                    "rule": AUTO_RULE,
                    **selection.describe(),
                },
            },
            "warnings": [w.model_dump() for w in plausibility_warnings(problem)],
        }
    )
