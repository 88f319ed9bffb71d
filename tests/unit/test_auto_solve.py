"""Auto through ``solve_problem``: it picks a method and succeeds, passes a failure on to the next
method, cross-checks a success with a second method, and stops whole on a cancel or its budget."""

from __future__ import annotations

import copy
from typing import Any

import pytest

from app.schemas import ProblemDocument
from app.schemas.result import ResultDocument
from worker.solver.api import solve_problem
from worker.solver.scenarios import get_scenario

pytestmark = pytest.mark.slow

CASE1 = "rlv-max-terminal-velocity"  # fixed final time: foh-ptr first, then cheb-scvx


def _doc(scenario: str, method: dict[str, Any] | None) -> ProblemDocument:
    document = copy.deepcopy(get_scenario(scenario).problem)
    if method is None:
        del document["method"]
    else:
        document["method"] = method  # no name: auto
    return ProblemDocument.model_validate(document)


def _solve(doc: ProblemDocument, **hooks: Any) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    streamed: list[dict[str, Any]] = []
    result = solve_problem(doc, on_iteration=streamed.append, **hooks)
    ResultDocument.model_validate(result)
    return result, streamed


def _tags(history: list[dict[str, Any]]) -> list[tuple[int, int, str]]:
    return [(r["iteration"], r["extra"]["auto_attempt"], r["extra"]["method"]) for r in history]


def test_a_document_without_a_method_is_solved_by_the_method_auto_picks() -> None:
    result, streamed = _solve(_doc("rlv-min-heat-load", {"nodes": 41}))
    assert (result["status"], result["method"]) == ("succeeded", "energy-scp")
    (attempt,) = result["attempts"]
    assert (attempt["method"], attempt["status"], attempt["kept"]) == (
        "energy-scp",
        "succeeded",
        True,
    )
    assert attempt["options"]["nodes"] == 41
    assert attempt["objective"] == result["objective"]["value"]
    assert attempt["iterations"] == len(result["history"]) == result["timing"]["iterations"]
    selection = result["provenance"]["selection"]
    assert (selection["chosen"], selection["candidates"]) == ("energy-scp", ["energy-scp"])
    assert "energy-scp is the first" in selection["reason"]
    assert set(selection["refused"]) == {"foh-ptr", "hp-scp", "cheb-scvx", "lgl-sqp"}
    assert result["provenance"]["method_options"]["name"] == "auto"
    assert streamed == result["history"]
    assert {(a, m) for _, a, m in _tags(result["history"])} == {(1, "energy-scp")}


def test_a_method_that_fails_passes_the_problem_to_the_next() -> None:
    """foh-ptr with one iteration fails at once; cheb-scvx is tried next (here held to two
    iterations, so the run ends with both reasons)."""
    method = {
        "overrides": {
            "foh-ptr": {"max_iterations": 1},
            "cheb-scvx": {"nodes": 41, "max_iterations": 2},
        }
    }
    result, streamed = _solve(_doc(CASE1, method))
    first, second = result["attempts"]
    assert (first["method"], first["status"]) == ("foh-ptr", "failed")
    assert (second["method"], second["status"]) == ("cheb-scvx", "failed")
    assert second["first_iteration"] == first["iterations"] + 1
    tags = _tags(result["history"])
    assert [i for i, _, _ in tags] == list(range(1, len(tags) + 1))  # numbered on
    assert [(a, m) for _, a, m in tags] == [(1, "foh-ptr")] * first["iterations"] + [
        (2, "cheb-scvx")
    ] * second["iterations"]
    assert streamed == result["history"]
    assert result["status"] == "failed"
    message = result["failure"]["message"]
    assert message.startswith("no method succeeded (the advice is attempt ")
    assert "attempt 1, foh-ptr (history iterations 1-2): infeasible: " in message
    assert f"attempt 2, cheb-scvx (history iterations 3-{len(tags)}): " in message
    assert result["method"] in ("foh-ptr", "cheb-scvx")
    assert result["provenance"]["selection"]["chosen"] is None


def test_a_cross_check_reports_both_values_and_keeps_the_better() -> None:
    method = {"cross_check": True, "overrides": {"cheb-scvx": {"nodes": 101}}}
    result, _ = _solve(_doc(CASE1, method))
    assert result["status"] == "succeeded"
    first, second = result["attempts"]
    assert (first["method"], first["purpose"], first["status"]) == (
        "foh-ptr",
        "answer",
        "succeeded",
    )
    assert (second["method"], second["purpose"]) == ("cheb-scvx", "cross_check")
    assert second["status"] == "succeeded"
    cross = result["cross_check"]
    assert cross["values"] == [first["objective"], second["objective"]]
    difference = abs(first["objective"] - second["objective"]) / max(
        first["objective"], second["objective"]
    )
    assert cross["relative_difference"] == pytest.approx(difference)
    assert cross["agree"] is (difference <= 0.005)
    kept = first if first["objective"] >= second["objective"] else second  # maximized
    assert result["method"] == kept["method"] and kept["kept"]
    assert result["objective"]["value"] == kept["objective"]


def test_a_cancel_stops_the_whole_run() -> None:
    result, _ = _solve(_doc(CASE1, {}), should_stop=lambda: True)
    assert result["status"] == "cancelled"
    assert [a["method"] for a in result["attempts"]] == ["foh-ptr"]
    assert result["failure"]["message"].startswith("stopped during auto's attempts; ")


def test_the_budget_covers_every_attempt() -> None:
    """An attempt that uses up auto's time limit ends the run: the next method is not tried."""
    result, _ = _solve(_doc(CASE1, {"time_limit_s": 0.05}))
    assert [(a["method"], a["status"]) for a in result["attempts"]] == [("foh-ptr", "timed_out")]
    assert (result["status"], result["failure"]["code"]) == ("timed_out", "time_limit")
    assert result["failure"]["message"].startswith("auto's time limit of 0.05 s for all attempts")
    assert (
        "raise method.time_limit_s (auto's 0.05 s for all attempts)" in result["failure"]["advice"]
    )
