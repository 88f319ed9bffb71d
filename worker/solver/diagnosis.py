"""Why a solve failed, in terms a user can act on: what was still moving when the budget ran
out, and what to change (a limit out of reach, a mesh too coarse between nodes, a budget too
small), read from the result's history, verification and failure code.

Each piece of advice names the field to change and the figure that points to it; nothing here
changes the status or the failure code.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from app.schemas.methods import ScpRunOptions
from worker.solver.scp.loop import VIRTUAL_CONTROL_TOL

PATH_FIELDS = {
    "heat_rate_W_m2": ("heat-rate", "path_constraints.heat_rate.max_W_m2"),
    "dynamic_pressure_Pa": ("dynamic-pressure", "path_constraints.dynamic_pressure.max_Pa"),
    "load_factor_g": ("load-factor", "path_constraints.load_factor.max_g"),
}
"""Verification path peak -> (what it is, the problem field of its limit)."""

BUDGET_CODES = frozenset({"max_iterations", "time_limit"})


def stall_note(last: Mapping[str, Any] | None, options: ScpRunOptions) -> str | None:
    """What ``last``, the last iteration of the run whose answer is reported, still changed,
    against the stop tolerances (at most three states, the farthest first), and an unspent
    virtual control; None without an iteration. Its number is the history's (a run of several
    starts numbers on from one start to the next)."""
    if last is None:
        return None
    tolerances = getattr(options, "stop_tolerance", None)
    changes = last.get("max_state_change") or {}
    over: list[tuple[float, str]] = []
    if isinstance(changes, Mapping) and tolerances is not None:
        for state, change in changes.items():
            tolerance = getattr(tolerances, state, None)
            if isinstance(change, int | float) and tolerance and abs(change) > tolerance:
                over.append(
                    (
                        abs(change) / tolerance,
                        f"{state} by {abs(change):.4g} (tolerance {tolerance:g})",
                    )
                )
    parts = []
    if over:
        moved = ", ".join(text for _, text in sorted(over, reverse=True)[:3])
        parts.append(f"the last step (iteration {last.get('iteration')}) still moved {moved}")
    virtual = last.get("virtual_control_norm")
    if isinstance(virtual, int | float) and virtual > VIRTUAL_CONTROL_TOL:
        parts.append(
            f"its virtual control was {virtual:.3g} (a converged step has at most "
            f"{VIRTUAL_CONTROL_TOL:g}): the linearized dynamics or constraints were not met yet"
        )
    return "; ".join(parts) or None


RELAXATION_GAP = 1.0e-3
"""A lift-vector method's last relaxation gap above which the advice names it."""


def _relaxation_gap(document: Mapping[str, Any]) -> tuple[float, bool] | None:
    """The last iteration's relaxation gap of a lift-vector method when it is not spent, and
    whether the vehicle's angle of attack follows a schedule (the gap is then lift unused)."""
    history = document.get("history") or []
    if document.get("method") != "cheb-scvx" or not history:
        return None
    gap = history[-1].get("relaxation_gap")
    if gap is None or gap <= RELAXATION_GAP:
        return None
    scheduled = (history[-1].get("extra") or {}).get("lift_law") == "schedule"
    return float(gap), scheduled


def advice(document: Mapping[str, Any], options: ScpRunOptions) -> list[str]:
    """What a user can change to make this failed result succeed, most likely first."""
    failure = document.get("failure") or {}
    code = failure.get("code")
    out: list[str] = []
    relaxed = _relaxation_gap(document)
    if relaxed is not None and relaxed[1]:
        weight = float(getattr(options, "weight_unused_lift", 0.0))
        out.append(
            f"the relaxed lift vector is not tight (|(u1, u2)|^2 falls short of 1 by "
            f"{relaxed[0]:.3g}): the optimizer asks for less lift than the angle-of-attack "
            f"schedule gives, which the vehicle cannot fly; raise method.weight_unused_lift "
            f"(it was {weight:g}), give more nodes, or relax the bank-rate limit"
        )
    elif relaxed is not None:
        gap = relaxed[0]
        out.append(
            f"the relaxed lift cone is not tight (u3 exceeds u1^2 + u2^2 by {gap:.3g}): the "
            "optimizer asks for drag without its lift, which no vehicle flies; the objective "
            "rewards shedding energy (a target near for the entry speed, a fixed final time). "
            "The relaxation is exact where drag always costs: minimum time over a long range, "
            "maximum terminal speed with a free final time"
        )
    if code == "max_iterations":
        out.append(
            f"raise method.max_iterations (it was {options.max_iterations}): the iterates were "
            "still moving; or start from a neighbouring answer (initial_guess)"
        )
    elif code == "time_limit":
        out.append(
            f"raise method.time_limit_s (it was {options.time_limit_s:g} s of CPU time), or "
            "start from a neighbouring answer (initial_guess)"
        )
    elif code == "diverged":
        out.append(
            "a step left the physical range: give a heavier trust region (method options), "
            "more nodes, or a start near the answer (initial_guess)"
        )
    elif code == "numerical_error":
        out.append(
            "the subproblem's numbers broke down: check the problem's units (metres, m/s, "
            "degrees) and limits, or try more nodes"
        )
    if out:  # the run stopped short: the last iterate's misses are its symptoms, not causes
        return out
    verification = document.get("verification") or {}
    converged_nodes = code == "verification_failed"
    out += _path_advice(verification, converged_nodes, options)
    out += _terminal_advice(verification, converged_nodes, options)
    out += _zone_and_control_advice(verification, options)
    if code == "infeasible" and not out:
        out.append(
            "the constraints could not all be met from this start: relax a path limit or a "
            "terminal target (a soft target costs instead of binding), or give initial_guess"
        )
    if code in ("infeasible", "verification_failed") and not any("nodes" in a for a in out):
        out.append(f"if the limits and targets are right: {_finer_mesh(options)}")
    return list(dict.fromkeys(out))


def _finer_mesh(options: ScpRunOptions) -> str:
    grid = getattr(options, "grid", None)
    more = f"more nodes (method.nodes, now {options.nodes})"
    return f"{more}, or the adaptive grid (method.grid)" if grid == "uniform" else more


def _path_advice(
    verification: Mapping[str, Any], converged_nodes: bool, options: ScpRunOptions
) -> list[str]:
    out = []
    for key, peak in (verification.get("path_maxima") or {}).items():
        if not isinstance(peak, Mapping) or peak.get("within") is not False:
            continue
        what, field = PATH_FIELDS.get(key, (key, key))
        ratio = peak.get("ratio")
        at = peak.get("at_time_s")
        figure = f"the flown {what} peaks at {ratio:.3f} x its limit at t = {at:.0f} s"
        if converged_nodes and ratio is not None and ratio < 1.2:
            out.append(f"{figure}, between nodes: {_finer_mesh(options)}")
        else:
            out.append(f"{figure}: the limit may be out of reach; relax {field}")
    return out


def _terminal_advice(
    verification: Mapping[str, Any], converged_nodes: bool, options: ScpRunOptions
) -> list[str]:
    missed = [
        name
        for name, check in (verification.get("terminal_error_vs_target") or {}).items()
        if isinstance(check, Mapping) and check.get("within") is False
    ]
    if not missed:
        return []
    listed = ", ".join(missed)
    if converged_nodes:
        return [
            f"the flight misses terminal {listed} although the nodes meet them: the "
            f"dynamics are resolved too coarsely; {_finer_mesh(options)}"
        ]
    return [
        f"terminal {listed} missed: a target may be out of reach with these limits; make "
        f'it soft (terminal.<state>: {{"kind": "soft"}}) or relax the path limits'
    ]


def _zone_and_control_advice(verification: Mapping[str, Any], options: ScpRunOptions) -> list[str]:
    out = []
    for zone in verification.get("no_fly_zones") or []:
        if isinstance(zone, Mapping) and zone.get("within") is False:
            name = zone.get("name") or "a zone"
            out.append(
                f"no-fly zone {name} entered by {-zone['min_clearance_deg']:.3f} deg of arc "
                f"on the flown path: {_finer_mesh(options)}"
            )
    for key, peak in (verification.get("control_limits") or {}).items():
        if isinstance(peak, Mapping) and peak.get("within") is False:
            out.append(
                f"the flown {key} reaches {peak['ratio']:.3f} x its limit between nodes: "
                f"{_finer_mesh(options)}"
            )
    return out


START_CODES = frozenset({"initial_guess", "path_limits_infeasible"})
"""Failures of a method that could not start: an implausible input is then the likely cause."""


def input_advice(document: Mapping[str, Any]) -> list[str]:
    """The result's implausible inputs (its plausibility warnings), to check before anything
    else: a slip of units makes every other symptom follow from it."""
    return [
        f"check the input first: {warning['message']}"
        for warning in document.get("warnings") or []
        if isinstance(warning, Mapping) and warning.get("message")
    ]


def blame_input(failure: dict[str, Any], warnings: Sequence[Mapping[str, Any]]) -> None:
    """A method that could not start from an implausible input says that, not what its own
    start options would change (``give method.initial_bank_deg``): what happened is kept, the
    implausible input named."""
    if failure.get("code") not in START_CODES or not warnings:
        return
    what = str(failure.get("message", "")).split("; ")[0]
    first = warnings[0].get("message", "")
    more = f" (and {len(warnings) - 1} more implausible inputs)" if len(warnings) > 1 else ""
    failure["message"] = f"{what}; the likely cause is an implausible input: {first}{more}"
