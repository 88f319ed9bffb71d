"""What a failed result tells its user to change (pure logic on hand-made result documents):
the stall of a run out of budget, a limit out of reach, a mesh too coarse between nodes."""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import pytest

from app.schemas import ProblemDocument
from app.schemas.methods import LglSqpOptions
from app.schemas.methods.energy_scp import EnergyScpOptions
from app.schemas.methods.foh_ptr import FohPtrOptions
from worker.solver.api import explain, solve_problem
from worker.solver.diagnosis import advice, stall_note
from worker.solver.methods.lgl_sqp.method import over_limit, sqp_failure_lead
from worker.solver.methods.lgl_sqp.sqp import SqpOutcome
from worker.solver.scenarios import get_scenario

FOH = FohPtrOptions(name="foh-ptr", grid="uniform", nodes=40, max_iterations=30)
ENERGY = EnergyScpOptions(name="energy-scp", nodes=121)


def _failed(code: str, verification: dict[str, Any] | None = None, **extra: Any) -> dict[str, Any]:
    return {
        "status": "failed",
        "failure": {"code": code, "message": "why"},
        "history": extra.get("history", []),
        "verification": verification,
    }


def test_a_run_out_of_iterations_says_what_still_moved_and_what_to_raise() -> None:
    history = [
        {"iteration": 1, "max_state_change": {"altitude_m": 5000.0}, "virtual_control_norm": 1.0},
        {
            "iteration": 2,
            "max_state_change": {"altitude_m": 412.0, "heading_deg": 0.01, "velocity_m_s": 30.0},
            "virtual_control_norm": 3e-3,
        },
    ]
    note = stall_note(history[-1], FOH)
    assert note is not None
    # velocity 30 m/s is 6 x its 5 m/s tolerance, altitude 412 m 4.1 x its 100 m: farthest first
    assert note.startswith(
        "the last step (iteration 2) still moved velocity_m_s by 30 (tolerance 5), "
        "altitude_m by 412"
    )
    assert "heading_deg" not in note  # within its tolerance
    assert "virtual control was 0.003" in note
    document = _failed(
        "max_iterations", {"path_maxima": {"heat_rate_W_m2": {"within": False}}}, history=history
    )
    explain(document, FOH)
    assert document["failure"]["message"] == f"why; {note}"
    # an unconverged iterate misses its limits: only the budget is advised
    assert document["failure"]["advice"] == [
        "raise method.max_iterations (it was 30): the iterates were still moving; or start "
        "from a neighbouring answer (initial_guess)"
    ]


def test_a_limit_out_of_reach_names_its_field_and_the_flown_peak() -> None:
    peak = {"max": 6.0e6, "limit": 1.0e6, "ratio": 6.0, "at_time_s": 296.0, "within": False}
    hints = advice(_failed("infeasible", {"path_maxima": {"heat_rate_W_m2": peak}}), ENERGY)
    assert hints[0] == (
        "the flown heat-rate peaks at 6.000 x its limit at t = 296 s: the limit may be out of "
        "reach; relax path_constraints.heat_rate.max_W_m2"
    )
    assert hints[-1] == "if the limits and targets are right: more nodes (method.nodes, now 121)"


def test_a_converged_answer_failing_between_nodes_asks_for_a_finer_mesh() -> None:
    verification = {
        "path_maxima": {"load_factor_g": {"ratio": 1.04, "at_time_s": 900.0, "within": False}},
        "terminal_error_vs_target": {
            "altitude_m": {"within": False},
            "heading_deg": {"within": True},
        },
        "no_fly_zones": [{"name": "wall", "min_clearance_deg": -0.2, "within": False}],
        "control_limits": {"bank_deg": {"ratio": 1.3, "within": False}},
    }
    hints = advice(_failed("verification_failed", verification), FOH)
    finer = "more nodes (method.nodes, now 40), or the adaptive grid (method.grid)"
    assert hints == [
        f"the flown load-factor peaks at 1.040 x its limit at t = 900 s, between nodes: {finer}",
        "the flight misses terminal altitude_m although the nodes meet them: the dynamics are "
        f"resolved too coarsely; {finer}",
        f"no-fly zone wall entered by 0.200 deg of arc on the flown path: {finer}",
        f"the flown bank_deg reaches 1.300 x its limit between nodes: {finer}",
    ]


def test_succeeded_and_cancelled_results_are_left_alone() -> None:
    for status in ("succeeded", "cancelled"):
        document = {
            "status": status,
            "failure": {"code": "cancelled", "message": "m"},
            "history": [],
        }
        explain(document, FOH)
        assert "advice" not in document["failure"] and document["failure"]["message"] == "m"


def test_an_unspent_lift_relaxation_is_named_first() -> None:
    """A lift-vector run whose cone is not tight (drag asked for without its lift) says so
    before anything else; below the threshold, or for another method, nothing is said."""
    from app.schemas.methods.cheb_scvx import ChebScvxOptions

    cheb = ChebScvxOptions()
    document = _failed("verification_failed", {}, history=[{"relaxation_gap": 4.0}])
    document["method"] = "cheb-scvx"
    tips = advice(document, cheb)
    assert tips and tips[0].startswith("the relaxed lift cone is not tight (u3 exceeds")
    document["history"] = [{"relaxation_gap": 1e-9}]
    assert not any("lift cone" in tip for tip in advice(document, cheb))
    document["history"] = [{"relaxation_gap": 4.0}]
    document["method"] = "foh-ptr"
    assert not any("lift cone" in tip for tip in advice(document, FOH))


def test_a_scheduled_vehicles_unused_lift_is_named_with_its_weight() -> None:
    """For a vehicle on an angle-of-attack schedule the gap is lift left unused (not drag asked
    for): the advice says so and names the option that prices it, with its value."""
    from app.schemas.methods.cheb_scvx import ChebScvxOptions

    cheb = ChebScvxOptions(weight_unused_lift=0.5)
    history = [{"relaxation_gap": 0.43, "extra": {"lift_law": "schedule"}}]
    document = _failed("verification_failed", {}, history=history)
    document["method"] = "cheb-scvx"
    tips = advice(document, cheb)
    assert tips[0].startswith("the relaxed lift vector is not tight (|(u1, u2)|^2 falls short")
    assert "method.weight_unused_lift (it was 0.5)" in tips[0]
    assert not any("drag without its lift" in tip for tip in tips)


@pytest.mark.slow
def test_a_run_of_two_starts_counts_its_iterations_one_way() -> None:
    """foh-ptr runs two starts of ``max_iterations`` each and reports the first when neither
    converges: the message names that start and where its iterations are in the history, and
    the stall note is its last step (not the other start's)."""
    raw = dict(get_scenario("rlv-max-terminal-velocity").problem)
    raw["method"] = {**raw["method"], "max_iterations": 3}
    result = solve_problem(ProblemDocument.model_validate(raw))
    assert result["failure"]["code"] == "max_iterations"
    assert [(s["start"], s["iterations"], s["chosen"]) for s in result["starts"]] == [
        (1, 3, True),
        (2, 3, False),
    ]
    assert result["timing"]["iterations"] == len(result["history"]) == 6
    message = result["failure"]["message"]
    assert message.startswith(
        "start 1 of 2 (history iterations 1-3): not converged in 3 iterations; "
        "the last step (iteration 3) still moved"
    ), message
    assert set(re.findall(r"iteration (\d+)\)", message)) == {"3"}


def test_a_path_value_over_its_limit_reads_as_over() -> None:
    assert over_limit(1.2e-6) == "0.00012 % over its limit"
    assert over_limit(0.034) == "3.4 % over its limit"
    assert over_limit(2.5) == "250 % over its limit"


def _outcome(status: str, message: str | None = None) -> SqpOutcome:
    return SqpOutcome(status=status, z=np.zeros(1), evaluation=None, message=message)  # type: ignore[arg-type]


def test_an_sqp_message_counts_what_the_history_holds() -> None:
    """The SQP's iterations and the global search's generations are both records of the
    history (``timing.iterations``): the message counts the SQP's and says where they are."""
    options = LglSqpOptions(name="lgl-sqp", max_iterations=300)
    lead = sqp_failure_lead(_outcome("max_iterations"), options, 400, 100, 0)
    assert lead == (
        "not converged in 300 SQP iterations (history records 101-400; records 1-100 are the "
        "GA search's generations)"
    )
    lead = sqp_failure_lead(_outcome("max_iterations"), options, 398, 100, 0)
    assert lead.startswith("not converged in 300 SQP iterations (2 of them a failed QP")
    options = LglSqpOptions(name="lgl-sqp", initial_guess="constant", time_limit_s=60)
    lead = sqp_failure_lead(
        _outcome("timed_out", "time limit 60 s reached after 9"), options, 50, 0, 12
    )
    assert lead == (
        "time limit 60 s reached after 50 SQP iterations (history records 1-50, the last 12 on "
        "the refined mesh)"
    )
    stalled = _outcome("infeasible", "the steps stalled at iteration 37 with conditions unmet")
    assert sqp_failure_lead(stalled, options, 37, 0, 0).startswith(
        "the steps stalled at iteration 37"
    )
