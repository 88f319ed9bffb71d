"""The registry of solution methods: what each supports, its defaults, and how it is run.

``check_support`` refuses, with a field path and a reason, any feature of a problem that the
chosen method cannot handle, so a request fails fast with 422 instead of deep in a worker.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from app.schemas import METHOD_OPTIONS, FieldIssue, ProblemDocument
from app.schemas.methods import FohPtrOptions
from worker.solver.method_result import IterationSink, MethodResult, StopCheck
from worker.solver.problem import EntryProblem

SupportCheck = Callable[[ProblemDocument], list[FieldIssue]]
Runner = Callable[[EntryProblem, Any, IterationSink | None, StopCheck | None], MethodResult]


@dataclass(frozen=True)
class MethodInfo:
    """A selectable method: its name, what it is, where it comes from, what it supports."""

    name: str
    title: str
    paper: str
    features: tuple[str, ...]
    objectives: tuple[str, ...]
    check: SupportCheck
    run: Runner

    def describe(self) -> dict[str, Any]:
        """JSON-ready description with the default options of the method."""
        return {
            "name": self.name,
            "title": self.title,
            "paper": self.paper,
            "features": list(self.features),
            "objectives": list(self.objectives),
            "default_options": METHOD_OPTIONS[self.name]().model_dump(mode="json"),
        }


def _issue(field: str, message: str, code: str = "unsupported_by_method") -> FieldIssue:
    return FieldIssue(field=field, message=message, code=code)


ENERGY_SCP_OBJECTIVES = (
    "min_heat_load",
    "min_time",
    "max_final_latitude",
    "min_final_latitude",
    "max_final_longitude",
    "min_final_longitude",
)


def _scheduled_alpha_issues(doc: ProblemDocument, name: str) -> list[FieldIssue]:
    """Refusals shared by methods that fly a scheduled angle of attack with CL(alpha), CD(alpha)."""
    out = []
    if doc.vehicle.angle_of_attack.mode == "optimized":
        out.append(
            _issue(
                "vehicle.angle_of_attack",
                f"{name} flies a scheduled angle of attack; "
                "give a velocity_schedule, table or constant",
            )
        )
    if doc.vehicle.aerodynamics.model == "parabolic_polar":
        out.append(
            _issue(
                "vehicle.aerodynamics",
                f"{name} needs CL and CD as functions of angle "
                "of attack (polynomial or table), not a normalized-lift polar",
            )
        )
    if doc.control_limits.alpha_rate_max_deg_s is not None:
        out.append(
            _issue(
                "control_limits.alpha_rate_max_deg_s",
                f"{name} does not optimize the angle of attack",
            )
        )
    return out


def _check_energy_scp(doc: ProblemDocument) -> list[FieldIssue]:
    """Features the energy-domain method of paper 000 cannot express, and energy consistency."""
    name = "energy-scp"
    out: list[FieldIssue] = []
    if doc.final_time.kind == "fixed":
        out.append(
            _issue(
                "final_time",
                f"{name} cannot fix the final time: energy is its "
                "independent variable and time is an outcome; leave final_time free",
            )
        )
    out.extend(_scheduled_alpha_issues(doc, name))
    if doc.control_limits.bank_rate_max_deg_s is not None:
        out.append(
            _issue(
                "control_limits.bank_rate_max_deg_s",
                f"{name} has bank angle as a control, not a state, so it cannot limit its rate",
            )
        )
    if doc.no_fly_zones:
        out.append(_issue("no_fly_zones", f"{name} does not handle no-fly zones"))
    if doc.waypoints:
        out.append(_issue("waypoints", f"{name} does not handle waypoints"))
    for i, term in enumerate(doc.objective.terms):
        if term.name not in ENERGY_SCP_OBJECTIVES:
            out.append(
                _issue(
                    f"objective.terms[{i}].name",
                    f"{name} cannot minimize "
                    f"{term.name!r}; it supports {', '.join(ENERGY_SCP_OBJECTIVES)}",
                )
            )
        if term.name == "min_heat_load" and doc.path_constraints.heat_rate is None:
            out.append(
                _issue(
                    "path_constraints.heat_rate",
                    "min_heat_load needs the heating "
                    "model (k_q and exponents) in path_constraints.heat_rate",
                )
            )
    # energy bounds: e = R0/r - V^2 / (2 g0 R0) (paper 000 eq. 7)
    planet = doc.planet
    g0r = planet.surface_gravity_m_s2 * planet.radius_m
    s0 = doc.initial_state
    e0 = planet.radius_m / (planet.radius_m + s0.altitude_m) - s0.velocity_m_s**2 / (2.0 * g0r)
    energy = doc.energy
    if energy is not None and energy.initial is not None and abs(energy.initial - e0) > 1e-4:
        out.append(
            _issue(
                "energy.initial",
                f"energy.initial {energy.initial} disagrees with the "
                f"initial state's energy {e0:.6f}; omit it or make them agree",
                "inconsistent",
            )
        )
    alt = doc.terminal.altitude_m
    vel = doc.terminal.velocity_m_s
    ef: float | None = None
    if energy is not None and energy.final is not None:
        ef = energy.final
        if vel.kind != "free":
            out.append(
                _issue(
                    "terminal.velocity_m_s",
                    "the terminal speed follows from "
                    "energy.final and the terminal altitude; leave it free",
                    "inconsistent",
                )
            )
    elif alt.kind == "fixed" and vel.kind == "fixed":
        rf = planet.radius_m / (planet.radius_m + alt.value)
        ef = rf - vel.value**2 / (2.0 * g0r)
    else:
        out.append(
            _issue(
                "energy.final",
                f"{name} needs the final energy: give energy.final, "
                "or a fixed terminal altitude and speed",
                "missing",
            )
        )
    if ef is not None:
        if ef <= e0:
            out.append(
                _issue(
                    "energy.final",
                    f"final energy {ef:.6f} is not above the initial "
                    f"energy {e0:.6f}: energy increases during entry",
                    "inconsistent",
                )
            )
        if alt.kind in ("fixed", "range", "soft"):
            lowest = alt.value if alt.kind != "range" else alt.lo
            if planet.radius_m / (planet.radius_m + lowest) <= ef:
                out.append(
                    _issue(
                        "terminal.altitude_m",
                        f"at final energy {ef:.6f} the terminal "
                        "altitude leaves no kinetic energy (V^2 <= 0)",
                        "inconsistent",
                    )
                )
    return out


def _run_energy_scp(
    model: EntryProblem,
    options: Any,
    on_iteration: IterationSink | None,
    should_stop: StopCheck | None,
) -> MethodResult:
    """Paper 000's energy-domain SCP, adapted to the common method result."""
    from worker.solver.scp.energy_scp import run_energy_scp, to_trajectory

    out = run_energy_scp(model, options, on_iteration=on_iteration, should_stop=should_stop)
    terms: dict[str, float] = {}
    if out.history:
        last = out.history[-1].cost_terms
        terms = {k.split(":", 1)[1]: v for k, v in last.items() if k.startswith("objective:")}
    return MethodResult(
        status=out.status,
        trajectory=to_trajectory(model, out) if out.history else None,
        history=out.history,
        conic_solve_s=out.conic_solve_s,
        objective_terms=terms,
        failure_code=out.failure_code,
        failure_message=out.failure_message,
    )


FOH_PTR_OBJECTIVES = (
    "max_terminal_velocity",
    "min_heat_load",
    "max_final_latitude",
    "min_final_latitude",
    "max_final_longitude",
    "min_final_longitude",
)


def _check_foh_ptr(doc: ProblemDocument) -> list[FieldIssue]:
    """Features the time-domain FOH method of paper 002 cannot express."""
    name = "foh-ptr"
    out: list[FieldIssue] = []
    if doc.final_time.kind != "fixed":
        out.append(
            _issue(
                "final_time",
                f"{name} needs a fixed final time (its grid is time with interval lengths "
                'summing to it); give final_time {"kind": "fixed", "value_s": ...}',
            )
        )
    out.extend(_scheduled_alpha_issues(doc, name))
    if doc.waypoints:
        out.append(_issue("waypoints", f"{name} does not handle waypoints yet"))
    if doc.energy is not None:
        out.append(
            _issue(
                "energy",
                f"{name} works in time and ignores energy bounds; leave energy out",
            )
        )
    for i, term in enumerate(doc.objective.terms):
        if term.name not in FOH_PTR_OBJECTIVES:
            out.append(
                _issue(
                    f"objective.terms[{i}].name",
                    f"{name} cannot optimize "
                    f"{term.name!r}; it supports {', '.join(FOH_PTR_OBJECTIVES)}",
                )
            )
        if term.name == "min_heat_load" and doc.path_constraints.heat_rate is None:
            out.append(
                _issue(
                    "path_constraints.heat_rate",
                    "min_heat_load needs the heating "
                    "model (k_q and exponents) in path_constraints.heat_rate",
                )
            )
    options = doc.method
    if isinstance(options, FohPtrOptions):
        lo, hi = options.interval_min_s, options.interval_max_s
        if lo > hi:
            out.append(
                _issue(
                    "method.interval_min_s",
                    f"interval_min_s {lo:g} exceeds interval_max_s {hi:g}",
                    "inconsistent",
                )
            )
        if doc.final_time.kind == "fixed":
            span = doc.final_time.value_s - doc.initial_state.time_s
            n = options.nodes - 1
            if options.grid == "adaptive" and not n * lo <= span <= n * hi:
                out.append(
                    _issue(
                        "method.nodes",
                        f"{n} intervals of {lo:g}..{hi:g} s cannot span the flight time "
                        f"{span:g} s; change nodes or the interval bounds",
                        "inconsistent",
                    )
                )
    return out


def _run_foh_ptr(
    model: EntryProblem,
    options: Any,
    on_iteration: IterationSink | None,
    should_stop: StopCheck | None,
) -> MethodResult:
    """Paper 002's time-domain SCP, adapted to the common method result."""
    from worker.solver.scp.foh_ptr import run_foh_ptr, to_trajectory

    out = run_foh_ptr(model, options, on_iteration=on_iteration, should_stop=should_stop)
    return MethodResult(
        status=out.status,
        trajectory=to_trajectory(model, out) if out.history else None,
        history=out.history,
        conic_solve_s=out.conic_solve_s,
        objective_terms=dict(out.objective_terms),
        failure_code=out.failure_code,
        failure_message=out.failure_message,
        extra=dict(out.extra),
    )


METHODS: dict[str, MethodInfo] = {
    "energy-scp": MethodInfo(
        name="energy-scp",
        title="Energy-domain SCP with post-correction",
        paper="Jung, Kim, Choi & Lee, Entry Vehicle Trajectory Optimization using Convex "
        "Programming and Post-correction Technique (paper 000)",
        features=(
            "energy as independent variable",
            "path limits (heat rate, dynamic pressure, load factor) as radius lower bounds",
            "bank magnitude limit",
            "terminal conditions fixed, range, free or soft",
            "rotating or non-rotating planet",
            "exponential or US76 atmosphere",
            "polynomial or tabulated aerodynamics with a scheduled angle of attack",
        ),
        objectives=ENERGY_SCP_OBJECTIVES,
        check=_check_energy_scp,
        run=_run_energy_scp,
    ),
    "foh-ptr": MethodInfo(
        name="foh-ptr",
        title="Time-domain SCP with exact FOH discretization and adaptive grid (experimental: "
        "converges to local optima below the reference; see docs/methods/foh-ptr.md)",
        paper="Ma, Chen, Wang & Zhang, Real-Time Trajectory Planning for Hypersonic Entry Using "
        "Adaptive Non-Uniform Discretization and Convex Optimization (paper 002)",
        features=(
            "time as independent variable, fixed final time",
            "bank angle as a state, bank rate as the control (first-order hold)",
            "inverse-free exact FOH discretization stitched to the propagated reference",
            "adaptive non-uniform grid (interval lengths as decision variables)",
            "path limits (heat rate, dynamic pressure, load factor), log-transformed",
            "no-fly zones",
            "bank magnitude and bank rate limits",
            "terminal conditions fixed, range, free or soft",
            "rotating or non-rotating planet",
            "exponential or US76 atmosphere",
            "polynomial or tabulated aerodynamics with a scheduled angle of attack",
        ),
        objectives=FOH_PTR_OBJECTIVES,
        check=_check_foh_ptr,
        run=_run_foh_ptr,
    ),
}


def list_methods() -> list[dict[str, Any]]:
    """Every method, JSON-ready, with its features and default options."""
    return [info.describe() for info in METHODS.values()]


def check_support(doc: ProblemDocument) -> list[FieldIssue]:
    """Issues that make ``doc`` unsolvable by its method (empty when it is fine)."""
    info = METHODS.get(doc.method.name)
    if info is None:
        return [_issue("method.name", f"unknown method {doc.method.name!r}", "unknown_method")]
    return info.check(doc)
