"""cheb-scvx's tie-breaking phase ends on the converged answer it started from when it stalls
or makes no progress over ``PHASE_WINDOW`` accepted steps (pure logic of
``ChebScvx._tie_breaking_ended`` on records; the solve that needs it, ``cheb-case1-active-nfz``,
runs in tests/unit/test_variants)."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

from worker.solver.methods.cheb_scvx.method import (
    PHASE_PROGRESS,
    PHASE_WINDOW,
    ChebScvx,
    _Converged,
)
from worker.solver.scp.history import IterationRecord


def record(
    iteration: int, virtual: float, gap: float, defect: float, infeasibility: float = 0.0
) -> IterationRecord:
    return IterationRecord(
        iteration=iteration,
        cost=0.0,
        cost_terms={},
        objective_value=None,
        max_state_change={},
        trust_region_slack=0.0,
        virtual_control_norm=virtual,
        linearization_error=defect,
        nodes_post_corrected=None,
        relaxation_gap=gap,
        conic_status="optimal",
        conic_solver="test",
        conic_solve_s=0.0,
        conic_setup_s=0.0,
        iteration_wall_s=0.0,
        extra={"infeasibility": infeasibility},
    )


KEPT: Any = object()
"""The converged reference (its identity is what the judgement must hand back)."""
LIN: Any = object()
START = record(25, 2e-9, 0.6, 0.0, 3e-4)


def method(phase: bool = True) -> Any:
    """A stand-in holding what the rule reads: the phase's converged answer and trail."""
    converged = _Converged(KEPT, LIN, 1e-9, START) if phase else None
    return SimpleNamespace(converged=converged, phase_trail=[])


def run(m: Any, infeasibilities: list[float], stalled: str | None = None) -> Any:
    """Judge one accepted phase step per value; the first verdict that ends it, or None."""
    for k, value in enumerate(infeasibilities):
        now = record(26 + k, 0.1, 0.001, 0.1, value)
        verdict = ChebScvx._tie_breaking_ended(m, now, False, stalled)
        if verdict is not None:
            return verdict, now
    return None


def test_no_phase_a_converged_step_or_the_converging_record_goes_on() -> None:
    late = record(500, 0.1, 0.0, 0.1, 1.0)
    assert ChebScvx._tie_breaking_ended(method(False), late, False, "stalled") is None
    assert ChebScvx._tie_breaking_ended(method(), late, True, None) is None
    assert ChebScvx._tie_breaking_ended(method(), START, False, None) is None


def test_a_phase_that_keeps_falling_goes_on() -> None:
    """Halving every 20 steps (suite problem 026's slowest stretch) is progress."""
    assert run(method(), [0.02 * 0.5 ** (k / PHASE_WINDOW) for k in range(200)]) is None


def test_a_flat_phase_ends_on_the_converged_answer_with_its_figures() -> None:
    values = [65.0, 30.0, 1.0] + [0.125] * 40
    ended = run(method(), values)
    assert ended is not None
    verdict, now = ended
    # the first step at which the value PHASE_WINDOW steps back was the flat one
    assert now.iteration == 26 + 3 + PHASE_WINDOW
    assert verdict.accepted and verdict.small
    assert verdict.reference is KEPT and verdict.linearization is LIN
    assert verdict.virtual_control == 1e-9
    # the record describes the kept answer; the phase's own figures stay beside them
    assert (now.virtual_control_norm, now.relaxation_gap, now.linearization_error) == (
        2e-9,
        0.6,
        0.0,
    )
    assert now.extra["phase"] == {
        "virtual_control_norm": 0.1,
        "relaxation_gap": 0.001,
        "linearization_error": 0.1,
    }
    assert "iteration 25 is kept" in now.extra["tie_breaking_ended"]


def test_a_stalled_phase_ends_at_once() -> None:
    ended = run(method(), [0.126], stalled="infeasibility stalled")
    assert ended is not None and ended[0].reference is KEPT
    assert ended[1].extra["tie_breaking_ended"].startswith("stalled")


def test_a_phase_falling_slower_than_its_progress_share_ends() -> None:
    """Over PHASE_WINDOW steps to halfway between PHASE_PROGRESS and 1 of itself: too slow."""
    share = (1.0 + PHASE_PROGRESS) / 2.0
    ended = run(method(), [share ** (k / PHASE_WINDOW) for k in range(100)])
    assert ended is not None
    assert ended[1].iteration == 26 + PHASE_WINDOW
