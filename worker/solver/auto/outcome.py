"""What auto's attempts add up to: each attempt's summary, the comparison of a cross-check, the
most informative failure, and the failure of a run in which nothing succeeded."""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

Purpose = Literal["answer", "cross_check"]

AGREEMENT = 0.005
"""Relative difference of two verified objective values above which a cross-check warns that
a local optimum is possible (0.5 %)."""


@dataclass
class Attempt:
    """One method run by auto: its place, its options and the result document it returned,
    and where its iterations sit in the combined history."""

    index: int
    name: str
    purpose: Purpose
    options: dict[str, Any]
    result: dict[str, Any]
    first: int
    count: int
    start_note: str | None = None

    @property
    def status(self) -> str:
        return str(self.result["status"])

    @property
    def succeeded(self) -> bool:
        return self.status == "succeeded"

    @property
    def failure(self) -> dict[str, Any]:
        return self.result.get("failure") or {}

    @property
    def objective(self) -> float | None:
        value = (self.result.get("objective") or {}).get("value")
        return float(value) if isinstance(value, int | float) else None

    def where(self) -> str:
        """The attempt and where its iterations are in the combined history."""
        if self.count == 0:
            span = "no iteration"
        elif self.count == 1:
            span = f"history iteration {self.first}"
        else:
            span = f"history iterations {self.first}-{self.first + self.count - 1}"
        return f"attempt {self.index}, {self.name} ({span})"

    def summary(self, kept: bool) -> dict[str, Any]:
        """The result's ``attempts`` entry."""
        failure = self.failure
        timing = self.result.get("timing") or {}
        return {
            "attempt": self.index,
            "method": self.name,
            "purpose": self.purpose,
            "status": self.status,
            "failure_code": failure.get("code"),
            "failure_message": failure.get("message"),
            "iterations": self.count,
            "first_iteration": self.first if self.count else None,
            "time_s": timing.get("total_s", timing.get("wall_s", 0.0)),
            "objective": self.objective,
            "kept": kept,
            "start": self.start_note,
            "options": self.options,
        }


def maximized(result: dict[str, Any]) -> bool:
    """Whether the result's objective value is to be maximized (a single ``max_`` term; a
    weighted sum is what the method minimized)."""
    name = str((result.get("objective") or {}).get("name") or "")
    return name.startswith("max_")


def better(a: Attempt, b: Attempt) -> Attempt:
    """The better of two succeeded attempts by their objective value (``a`` on a tie)."""
    va, vb = a.objective, b.objective
    if va is None or vb is None:
        return a if vb is None else b
    if maximized(a.result):
        return b if vb > va else a
    return b if vb < va else a


def compare(first: Attempt, second: Attempt) -> dict[str, Any]:
    """The result's ``cross_check``: both attempts' values, how far apart, and a warning when
    they differ by more than :data:`AGREEMENT`."""
    entry: dict[str, Any] = {
        "attempts": [first.index, second.index],
        "methods": [first.name, second.name],
        "values": [first.objective, second.objective],
        "relative_difference": None,
        "agree": None,
        "warning": None,
        "note": None,
    }
    if not second.succeeded:
        failure = second.failure
        entry["note"] = (
            f"the cross-check ({second.where()}) ended {second.status}"
            + (f" ({failure.get('code')})" if failure.get("code") else "")
            + ": one verified value only"
        )
        return entry
    va, vb = first.objective, second.objective
    if va is None or vb is None:
        entry["note"] = "a value is missing: nothing to compare"
        return entry
    difference = abs(va - vb) / max(abs(va), abs(vb), 1e-300)
    entry["relative_difference"] = difference
    entry["agree"] = difference <= AGREEMENT
    if not entry["agree"]:
        best = better(first, second)
        whose = best.name if first.name != second.name else f"attempt {best.index}"
        entry["warning"] = (
            f"{first.name} (attempt {first.index}) found {va:.6g} and {second.name} (attempt "
            f"{second.index}) {vb:.6g}, {100 * difference:.2f} % apart: a local optimum is "
            f"possible; the better verified value ({whose}'s) is kept"
        )
    return entry


_RANK = {
    "verification_failed": 1,
    "max_iterations": 2,
    "diverged": 3,
    "numerical_error": 3,
    "failed": 3,
    "time_limit": 4,
    "cancelled": 5,
}
"""How little a failure code says about the problem (lower: more). A code not listed names the
problem itself (path_limits_infeasible, a pre-check's) and ranks first; ``infeasible`` ranks
with a failed verification when the method converged, with a spent budget when it did not."""

_START_LABEL = re.compile(r"^start \d+ of \d+ \([^)]*\): ")


def _rank(attempt: Attempt) -> int:
    """The rank of ``attempt``'s failure (see :data:`_RANK`)."""
    code = str(attempt.failure.get("code"))
    if code == "infeasible":
        message = _START_LABEL.sub("", str(attempt.failure.get("message") or ""))
        return 1 if message.startswith("converged") else 2
    return _RANK.get(code, 0)


def most_informative(attempts: Sequence[Attempt]) -> Attempt:
    """The failed attempt that says most about the problem: by its failure's rank, then one
    with a trajectory, then the earlier (auto's preferred) one."""
    return min(attempts, key=lambda a: (_rank(a), a.result.get("trajectory") is None, a.index))


def advice_for_auto(hints: Sequence[str], name: str) -> list[str]:
    """A method's advice as it applies under auto: its options are auto's overrides of that
    method (``method.nodes`` -> ``method.overrides.<name>.nodes``), but for its time limit,
    which is what auto's own ``method.time_limit_s`` left it."""
    pattern = re.compile(r"\bmethod\.(?!time_limit_s\b|overrides\.)")
    return [pattern.sub(f"method.overrides.{name}.", hint) for hint in hints]


def failure_of_none(
    attempts: Sequence[Attempt],
    informative: Attempt,
    stop: str | None,
    time_limit_s: float,
    untried: Sequence[str],
) -> dict[str, Any]:
    """The failure of a run in which no attempt succeeded: the informative attempt's code (or
    the stop's), every attempt's reason in the message, the informative one's advice and what
    auto's own options could change."""
    reasons = "; ".join(
        f"{a.where()}: {a.failure.get('code') or a.status}: {a.failure.get('message') or ''}"
        for a in attempts
    )
    advice = advice_for_auto(informative.failure.get("advice") or [], informative.name)
    if stop == "cancelled":
        code, message = "cancelled", f"stopped during auto's attempts; {reasons}"
    elif stop == "timed_out":
        code = "time_limit"
        message = f"auto's time limit of {time_limit_s:g} s for all attempts ran out; {reasons}"
        advice.append(f"raise method.time_limit_s (auto's {time_limit_s:g} s for all attempts)")
    else:
        code = str(informative.failure.get("code") or "failed")
        message = (
            f"no method succeeded (the advice is attempt {informative.index}'s, whose failure "
            f"says most about the problem): {reasons}"
        )
    if untried and stop is None:
        advice.append(
            f"raise method.max_attempts to try {', '.join(untried)} too (they accept the problem)"
        )
    out: dict[str, Any] = {"code": code, "message": message}
    if advice:
        out["advice"] = list(dict.fromkeys(advice))
    return out
