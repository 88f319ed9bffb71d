"""The pre-checks' findings in a result: a refusal before the method runs, or the named cause
of a failed solve (``prechecks``).

A proof of infeasibility ends the solve before the method: failed, code ``infeasible``, the
figure in the message and ``failure.cause``. After a failed solve the likely causes lead the
message and the advice; a run that broke down (``diverged``, ``numerical_error``) or left
constraints unmet (``infeasible``) is then reported ``infeasible`` with that cause, since the
named input explains it better than the method's own trust-region symptoms. A budget that ran
out or a failed verification keeps its code (their figures are facts of the run) and gains the
cause. A success is never touched.
"""

from __future__ import annotations

import dataclasses
import logging
from typing import Any

from pydantic import ValidationError

from app.schemas import ProblemDocument
from worker.solver.methods import METHODS, check_support
from worker.solver.prechecks import Finding, PullUp, likely_causes, proven_infeasible
from worker.solver.problem import EntryProblem

log = logging.getLogger(__name__)

RENAMED_CODES = frozenset({"diverged", "infeasible", "numerical_error"})
"""Failure codes a named cause turns into ``infeasible``."""


def refusal(problem: EntryProblem) -> tuple[dict[str, Any] | None, PullUp | None]:
    """The failure of a problem the pre-checks prove infeasible (None when they prove nothing),
    and the least-bank pull-up they flew (for the likely causes of a later failure)."""
    findings, pull_up = proven_infeasible(problem)
    if not findings:
        return None, pull_up
    message = "infeasible before any iteration: " + "; ".join(f.message for f in findings)
    failure = {
        "code": "infeasible",
        "message": message,
        "advice": [f.advice for f in findings],
        "cause": findings[0].as_cause(),
    }
    return failure, pull_up


def free_time_methods(doc: ProblemDocument) -> list[str]:
    """The methods that take ``doc`` with a free final time (their default options)."""
    raw = doc.model_dump(mode="json", exclude_unset=True)
    raw["final_time"] = {"kind": "free"}
    found = []
    for name in METHODS:
        try:
            variant = ProblemDocument.model_validate({**raw, "method": {"name": name}})
        except ValidationError:
            continue
        if not check_support(variant):
            found.append(name)
    return found


def with_methods(finding: Finding, doc: ProblemDocument | None) -> Finding:
    """A final-time finding's advice naming the methods that take the problem with a free final
    time (the method to try, not only the setting)."""
    if finding.check != "final_time" or doc is None:
        return finding
    methods = free_time_methods(doc)
    if not methods:
        return finding
    named = f"with a method that takes it: {', '.join(methods)}"
    return dataclasses.replace(
        finding, advice=finding.advice.replace("with a method that takes one", named)
    )


def name_causes(
    document: dict[str, Any],
    problem: EntryProblem,
    pull_up: PullUp | None,
    doc: ProblemDocument | None = None,
) -> list[str]:
    """Name the likely causes of a failed (or timed-out) result in its failure, renaming a
    broken-down run ``infeasible``; the advice they give (to come first), empty when the result
    succeeded, was cancelled or no cause was found. ``doc``: the problem document, for the
    methods a final-time cause's advice names."""
    failure = document.get("failure")
    if document["status"] not in ("failed", "timed_out") or not failure:
        return []
    try:
        findings = [with_methods(f, doc) for f in likely_causes(problem, pull_up)]
    except (ArithmeticError, ValueError) as exc:  # advice only: the failure stands as it is
        log.warning("the pre-checks could not name a cause: %s", exc)
        return []
    if not findings:
        return []
    likely = [f for f in findings if not f.possible]
    causes = "; ".join(f.message for f in likely)
    maybe = "; ".join(f.message for f in findings if f.possible)
    if not likely:
        failure["message"] = f"{failure['message']}; possible cause: {maybe}"
    elif document["status"] == "failed" and failure["code"] in RENAMED_CODES:
        was = failure["code"]
        failure["code"] = "infeasible"
        failure["message"] = f"infeasible, likely because {causes} (the run ended {was}: " + (
            f"{failure['message']})"
        )
    else:
        failure["message"] = f"{failure['message']}; likely cause: {causes}"
    if likely and maybe:
        failure["message"] += f"; possible cause: {maybe}"
    failure["cause"] = _cause(findings)
    return [f.advice for f in findings]


def _cause(findings: list[Finding]) -> dict[str, Any]:
    """The first likely cause's record (the first possible one's when none is likely)."""
    return min(findings, key=lambda f: f.possible).as_cause()
