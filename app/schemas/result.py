"""The result document: what a solve returns, as stored by the service and written by the CLI.

Every nested record (trajectory, verification, history, provenance) is a model here, so the
OpenAPI document of ``/result`` and ``/history`` says what each field means and in which unit.
:func:`json_ready` is the one place where solver values become strict JSON.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from app.schemas.plausibility import PlausibilityWarning

ResultStatus = Literal["succeeded", "failed", "cancelled", "timed_out"]

Number = float | None
"""A finite number, or null where the value was NaN or infinite (JSON has neither)."""


def json_ready(value: Any) -> Any:
    """``value`` as strict JSON data: NaN and infinities become null, numpy scalars and arrays
    Python numbers and lists, dataclasses dicts, tuples lists, keys strings, anything else its
    text. Finite floats keep their exact value (the result documents are compared bitwise)."""
    if value is None or isinstance(value, str | int):  # bool is an int
        return value
    if isinstance(value, float):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k if isinstance(k, str) else str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(v) for v in value]
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return json_ready(dataclasses.asdict(value))
    if hasattr(value, "tolist"):  # numpy scalars and arrays
        return json_ready(value.tolist())
    return str(value)


class _Record(BaseModel):
    """A record whose fields are all known: an unknown key is a contract violation."""

    model_config = ConfigDict(extra="forbid")


class FailureCause(_Record):
    """The input a physical pre-check found binding: a limit the least-bank flight exceeds, a
    target out of reach, a zone across the corridor, a final time far from what the flight
    takes (docs/problem-contract.md, "Pre-checks")."""

    check: str = Field(
        ...,
        description="limit_below_pull_up, target_out_of_reach, zone_blocks_corridor or final_time.",
    )
    field: str = Field(..., description="The problem field to change, as a dotted path.")
    proven: bool = Field(
        ...,
        description="True: a necessary condition of every solution fails, so the problem has "
        "none (the solve was refused before the method ran); false: the likely cause.",
    )
    likely: bool = Field(
        True,
        description="True: the figure makes the input the likely cause; false: only a possible "
        "one (a fixed final time longer than the flights to the target take but within the "
        "longest flight's: a flight that wanders may last it), which does not turn a failure "
        "into infeasible.",
    )
    value: Number = Field(
        None, description="What the pre-check's flights or geometry reach, in ``units``."
    )
    limit: Number = Field(None, description="What the input asks, in ``units``.")
    units: str | None = Field(
        None, description="Unit of value and limit (W/m^2, Pa, g0, km, s, deg)."
    )


class Failure(_Record):
    """Why a solve did not succeed: a stable code and a readable message."""

    code: str = Field(
        ...,
        description="diverged (a step over the physical bounds of one iteration, or "
        "non-finite numbers), infeasible (which constraint, where, by how much), "
        "numerical_error, max_iterations, time_limit, verification_failed, cancelled, "
        "path_limits_infeasible, invalid_problem, unsupported_by_method "
        "(docs/problem-contract.md lists when each is given).",
    )
    message: str = Field(..., description="What happened, for people.")
    advice: list[str] = Field(
        default_factory=list,
        description="What to change to make it succeed, most likely first, each naming the "
        "field and the figure that points to it (absent when there is nothing to suggest).",
    )
    cause: FailureCause | None = Field(
        None,
        description="The binding input a physical pre-check found, with its figure (absent when "
        "none was found).",
    )


class ObjectiveValue(_Record):
    """The objective's value on the optimized trajectory (and after propagation when known)."""

    name: str = Field(..., description="Objective term name, or weighted_sum for several terms.")
    value: Number = Field(
        None,
        description="Value on the optimizer's nodes, in ``units``; for weighted_sum the sum of "
        "weight x term value over the terms in their own units, max terms negated (what the "
        "method minimized).",
    )
    units: str = Field(..., description="Unit of value and propagated_value (mixed for sums).")
    propagated_value: Number = Field(
        None, description="Same quantity on the propagated trajectory, where it is defined."
    )
    terms: dict[str, Number] = Field(
        default_factory=dict, description="Each term's value, in its own unit (SI, degrees)."
    )


class Timing(_Record):
    """Where the time went: the whole optimization, the conic solver's share, verification."""

    wall_s: float = Field(
        ...,
        description="Optimization wall time (SCP loop), s; the compiled kernels are loaded "
        "before it starts (their loading counts in total_s).",
    )
    conic_solve_s: float = Field(..., description="Sum of the conic solver's own solve times, s.")
    iterations: int = Field(..., description="SCP iterations run (length of history).")
    verification_s: float = Field(0.0, description="Propagation and checks, s.")
    total_s: float = Field(
        0.0, description="Whole solve including model building and kernel loading, s."
    )
    cpu_s: float | None = Field(
        None,
        description="CPU time of the solving process over the whole solve (every thread), s: "
        "the clock of method.time_limit_s.",
    )


class StateValues(BaseModel):
    """One number per state in SI units and degrees (only the states the context defines).

    The states of other models come by their names, which end in their unit as these do.
    """

    model_config = ConfigDict(extra="allow")

    time_s: Number = Field(None, description="Time, s.")
    altitude_m: Number = Field(None, description="Altitude above the reference sphere, m.")
    longitude_deg: Number = Field(None, description="Longitude, deg.")
    latitude_deg: Number = Field(None, description="Latitude, deg.")
    velocity_m_s: Number = Field(None, description="Speed relative to the rotating planet, m/s.")
    flight_path_angle_deg: Number = Field(None, description="Flight-path angle, deg.")
    heading_deg: Number = Field(None, description="Heading (from north, clockwise), deg.")
    bank_deg: Number = Field(None, description="Bank angle (bank-state models), deg.")
    alpha_deg: Number = Field(None, description="Angle of attack (alpha-state models), deg.")
    interval_s: Number = Field(None, description="Node interval (time-dilated methods), s.")


class HistoryExtra(BaseModel):
    """A method's own diagnostics of one iteration (foh-ptr: the keys below; energy-scp:
    ``weight_trust_region`` and the chatter/projection/regrid flags).

    Methods may add keys; those listed are documented with their units.
    """

    model_config = ConfigDict(extra="allow")

    max_interval_change_s: Number = Field(None, description="Largest node-interval change, s.")
    interval_s_min: Number = Field(None, description="Shortest node interval, s.")
    interval_s_max: Number = Field(None, description="Longest node interval, s.")
    path_ratio_at_nodes: dict[str, Number] | None = Field(
        None, description="Largest value / limit of each path constraint at the nodes (1)."
    )
    path_ratio_between_nodes: dict[str, Number] | None = Field(
        None, description="Largest value / limit of each path constraint between nodes (1)."
    )
    no_fly_zone_clearance_deg: list[Number] | None = Field(
        None, description="Each zone's smallest clearance over the nodes, deg."
    )
    no_fly_zone_window_nodes: list[list[int]] | None = Field(
        None, description="Each zone's [first, last] node of its engaged window."
    )
    discretization_s: Number = Field(None, description="Wall time of the discretization, s.")
    second_order_step: bool | None = Field(
        None, description="Whether the step used the second-order (SQP) curvature."
    )
    weight_trust_region: Number = Field(None, description="Trust-region weight used (1).")
    node_times_s: list[Number] | None = Field(None, description="Time of each node, s.")
    step_defect: Number = Field(None, description="Largest dynamics defect of the step (1).")
    start: int | None = Field(
        None, description="The start of a multi-start run the iteration belongs to (1-based)."
    )
    initial_bank_deg: Number = Field(
        None, description="Constant bank of that start's initial guess, deg."
    )
    auto_attempt: int | None = Field(
        None,
        description="For method auto, or a named method's second start: the attempt the "
        "iteration belongs to (1-based, the "
        "result's attempts[].attempt).",
    )
    method: str | None = Field(None, description="With auto_attempt: the method of that attempt.")


class HistoryRecord(BaseModel):
    """One SCP iteration: cost, step size, conic solve, timings (the solver's IterationRecord).

    Methods may add fields; ``extra`` holds method-specific diagnostics.
    """

    model_config = ConfigDict(extra="allow")

    iteration: int = Field(..., description="1 for the first iteration of the attempt.")
    cost: Number = Field(
        None, description="Objective on the iterate: SI units for one term, else normalized."
    )
    cost_terms: dict[str, Number] = Field(
        default_factory=dict,
        description="Each term of the subproblem's cost (objective:<name> in its SI unit, "
        "penalties nondimensional).",
    )
    objective_value: Number = Field(
        None, description="The problem's own objective on the new reference, SI units."
    )
    max_state_change: StateValues | Number = Field(
        None, description="Largest change of each state over the nodes (SI units, degrees)."
    )
    trust_region_slack: Number = Field(
        None,
        description="The step's squared length in the method's trust units (paper 000 eq. 31's "
        "t_i; 1): the sum of the squared scaled changes of the variables its trust region "
        "bounds (the trust region's own size is in extra: weight_trust_region, trust_radius, "
        "trust_weight or trust_box).",
    )
    virtual_control_norm: Number = Field(
        None,
        description="L1 norm of the step's virtual control and buffers, scaled (1); a "
        "converged answer has none.",
    )
    linearization_error: Number = Field(
        None,
        description="Largest dynamics defect the step leaves: the candidate's nodes against "
        "the nonlinear dynamics (the error of the step's linear model), trust units (1).",
    )
    nodes_post_corrected: int | None = Field(
        None,
        description="energy-scp: (node, state) pairs whose step was shortened (count); null "
        "for the other methods.",
    )
    relaxation_gap: Number = Field(
        None,
        description="Largest gap of a relaxed control cone (energy-scp: 1 - |u|; cheb-scvx: "
        "u3 - u1^2 - u2^2; 0 when tight; 1); null for methods without one.",
    )
    conic_status: str | None = Field(None, description='The conic solver\'s status, "optimal".')
    conic_solver: str | None = Field(None, description="The conic solver used, e.g. clarabel.")
    conic_solve_s: Number = Field(None, description="The conic solver's own solve time, s.")
    conic_setup_s: Number = Field(None, description="Building the conic problem, s.")
    iteration_wall_s: Number = Field(None, description="Wall time of the whole iteration, s.")
    conic_solver_setup_s: Number = Field(
        None, description="Inside the solver's own setup / data update (Clarabel), s."
    )
    subproblem_cost: Number = Field(
        None, description="The conic subproblem's objective (normalized units, 1)."
    )
    extra: HistoryExtra = Field(default_factory=HistoryExtra, description="Method diagnostics.")


class Trajectory(BaseModel):
    """The optimized trajectory as columns, one value per node, each column's unit in ``units``.

    Columns are present when the problem defines them (no heat rate without a heat model,
    ``energy`` for energy-domain methods only).
    """

    model_config = ConfigDict(extra="allow")

    nodes: int | None = Field(None, description="Number of nodes (length of every column).")
    units: dict[str, str] = Field(default_factory=dict, description="Unit of each column.")
    time_s: list[Number] | None = Field(None, description="Time of each node, s.")
    altitude_m: list[Number] | None = Field(None, description="Altitude, m.")
    longitude_deg: list[Number] | None = Field(None, description="Longitude, deg.")
    latitude_deg: list[Number] | None = Field(None, description="Latitude, deg.")
    velocity_m_s: list[Number] | None = Field(None, description="Relative speed, m/s.")
    flight_path_angle_deg: list[Number] | None = Field(None, description="Flight-path angle, deg.")
    heading_deg: list[Number] | None = Field(None, description="Heading, deg.")
    bank_deg: list[Number] | None = Field(None, description="Bank angle, deg.")
    alpha_deg: list[Number] | None = Field(None, description="Angle of attack, deg.")
    normalized_lift: list[Number] | None = Field(
        None,
        description="Normalized lift lambda = CL / CL* of a parabolic-polar vehicle (1), in the "
        "angle of attack's place.",
    )
    heat_rate_W_m2: list[Number] | None = Field(None, description="Stagnation heat rate, W/m^2.")
    dynamic_pressure_Pa: list[Number] | None = Field(None, description="Dynamic pressure, Pa.")
    load_factor_g: list[Number] | None = Field(
        None, description="Aerodynamic load factor, in standard gravities (g0)."
    )
    energy: list[Number] | None = Field(
        None, description="Normalized energy e = R0/r - V^2/(2 g0 R0) (1; energy methods)."
    )
    mass_kg: list[Number] | None = Field(
        None, description="Vehicle mass, kg (only with propulsion: it burns propellant)."
    )
    thrust_n: list[Number] | None = Field(
        None,
        description="Thrust acting, N (only with propulsion; it follows the command with the "
        "thruster's lag, when it has one).",
    )
    thrust_command_n: list[Number] | None = Field(
        None, description="Commanded thrust, N (only with propulsion)."
    )
    phase: list[int] | None = Field(
        None,
        description="Only for a flight in phases: the 0-based index of the phase each row "
        "belongs to (a phase's last row and the next one's first share their time).",
    )


class Integrator(_Record):
    """The integrator of the verification's propagation."""

    method: str = Field(..., description="scipy solve_ivp method, DOP853.")
    rtol: float = Field(..., description="Relative tolerance (1).")
    atol: float = Field(..., description="Absolute tolerance (nondimensional states).")
    steps: int = Field(..., description="Output points of the propagation (count).")


class VerificationTolerances(_Record):
    """What the verification accepts: terminal errors per state, path and zone margins."""

    altitude_m: float = Field(..., description="Terminal altitude, m.")
    longitude_deg: float = Field(..., description="Terminal longitude, deg.")
    latitude_deg: float = Field(..., description="Terminal latitude, deg.")
    velocity_m_s: float = Field(..., description="Terminal speed, m/s.")
    flight_path_angle_deg: float = Field(..., description="Terminal flight-path angle, deg.")
    heading_deg: float = Field(..., description="Terminal heading, deg.")
    path_limit_relative: float = Field(..., description="Allowed excess over a path limit (1).")
    no_fly_zone_deg: float = Field(..., description="Allowed intrusion into a no-fly zone, deg.")
    control_limit_relative: float = Field(
        0.01, description="Allowed excess of the flown bank (and bank rate) over its limit (1)."
    )
    objective_relative: float = Field(
        0.01,
        description="Allowed excess of the flown heat load (objective.propagated_value) over "
        "the optimized one (objective.value) (1).",
    )


class TerminalCheck(_Record):
    """The propagated final value of one state against its target."""

    kind: str = Field(..., description="The target's kind: fixed, range or soft.")
    error: Number = Field(..., description="Signed miss (range: distance outside it), state unit.")
    tolerance: Number = Field(..., description="Accepted miss, state unit.")
    within: bool = Field(..., description="|error| <= tolerance.")


class PathPeak(_Record):
    """The largest value of one path quantity (or control) on the propagated trajectory."""

    max: Number = Field(..., description="Peak value, the quantity's unit (W/m^2, Pa, g0).")
    at_time_s: Number = Field(..., description="When it peaks, s.")
    limit: Number = Field(None, description="The problem's limit, same unit (absent: none).")
    ratio: Number = Field(
        None,
        description="max / limit (1); in a flight in phases, the largest value / limit of "
        "`phase`, the phase where it is largest.",
    )
    within: bool | None = Field(None, description="max <= limit (1 + path_limit_relative).")
    phase: str | None = Field(
        None,
        description="Only for a flight in phases (each with its own limits): the phase whose "
        "limit is given, the one where value / limit is largest (max is the whole flight's).",
    )


class PathMaxima(_Record):
    """Peaks of the path quantities the problem defines."""

    heat_rate_W_m2: PathPeak | None = Field(None, description="Heat rate, W/m^2.")
    dynamic_pressure_Pa: PathPeak | None = Field(None, description="Dynamic pressure, Pa.")
    load_factor_g: PathPeak | None = Field(None, description="Load factor, g0.")


class ControlPeaks(_Record):
    """Peaks of the flown control between and at the nodes, against the control limits."""

    bank_deg: PathPeak | None = Field(
        None,
        description="|bank angle|, deg; with an asymmetric bank range the largest bank against "
        "bank_max_deg, its ratio the share of the range's half-width used from its middle.",
    )
    bank_min_deg: PathPeak | None = Field(
        None,
        description="Only with an asymmetric bank range: the smallest bank (in `max`) against "
        "the lower bound, its ratio the share of the half-width used from the range's middle.",
    )
    bank_rate_deg_s: PathPeak | None = Field(
        None, description="|bank rate|, deg/s (only when the problem limits it)."
    )
    alpha_max_deg: PathPeak | None = Field(
        None,
        description="Only with an optimized angle of attack: the largest alpha against its upper "
        "bound, the ratio the share of the range's half-width used from its middle.",
    )
    alpha_min_deg: PathPeak | None = Field(
        None,
        description="Only with an optimized angle of attack: the smallest alpha (in `max`) "
        "against its lower bound, the ratio as for alpha_max_deg.",
    )
    alpha_rate_deg_s: PathPeak | None = Field(
        None,
        description="|alpha rate|, deg/s (an optimized angle of attack with a rate bound).",
    )


class ZoneClearance(_Record):
    """The propagated trajectory's smallest clearance of one no-fly zone (negative: inside)."""

    name: str | None = Field(None, description="The zone's name, if it has one.")
    min_clearance_deg: Number = Field(..., description="Great-circle clearance, deg.")
    min_clearance_km: Number = Field(..., description="The same on the surface, km.")
    within: bool = Field(..., description="Clearance >= -no_fly_zone_deg.")
    latitude_deg: Number = Field(None, description="The zone's centre latitude, deg.")
    longitude_deg: Number = Field(None, description="The zone's centre longitude, deg.")
    radius_deg: Number = Field(None, description="The zone's radius, deg of arc.")
    metric: str | None = Field(
        None,
        description="great_circle (radius along the sphere) or lat_lon (a circle in the "
        "latitude-longitude plane, paper 002 eq. 27).",
    )


class WaypointPass(_Record):
    """The flown path's closest approach to one waypoint (after the previous one's)."""

    order: int = Field(..., description="The waypoint's place in the visiting sequence.")
    latitude_deg: Number = Field(..., description="Centre latitude, deg.")
    longitude_deg: Number = Field(..., description="Centre longitude, deg.")
    radius_deg: Number = Field(..., description="Radius, deg of arc.")
    metric: str | None = Field(None, description="great_circle or lat_lon, as for zones.")
    closest_deg: Number = Field(..., description="Closest approach to the centre, deg of arc.")
    at_time_s: Number = Field(..., description="When, s.")
    within: bool = Field(..., description="closest <= radius + no_fly_zone_deg.")


class PhaseCheck(_Record):
    """One phase of a flight in phases as propagated: when it ran and how its end met the
    phase's end conditions."""

    name: str = Field(..., description="The phase's name.")
    start_time_s: Number = Field(..., description="When the phase starts, s.")
    end_time_s: Number = Field(
        ...,
        description="When its propagation ended (its end time, unless the ground came first), s.",
    )
    reached_end: bool = Field(
        ..., description="The propagation reached the phase's end (false: it hit the ground)."
    )
    end_state: StateValues = Field(
        ...,
        description="The propagated state at the phase's end (SI, degrees), with mass_kg "
        "(propulsion) and thrust_n (a thrust that lags its command).",
    )
    end_error_vs_target: dict[str, TerminalCheck] = Field(
        default_factory=dict,
        description="Per state with an end condition in this phase: the miss of its target.",
    )
    within: bool = Field(
        ..., description="Every fixed and range end condition of the phase met within tolerance."
    )


class PropagatedPath(Trajectory):
    """The propagated flight on the verification's dense grid (about 20 samples between nodes,
    thinned to at most about 1 000 rows with every reported peak kept): the same columns and
    units as the optimized trajectory, for overlaying one on the other."""

    samples: int | None = Field(None, description="Number of rows (length of every column).")


class Verification(_Record):
    """Propagation of the optimized controls through the nonlinear dynamics, and its checks."""

    feasible: bool = Field(
        ...,
        description="Reached the end, hard targets, paths, zones and control limits met (in "
        "phases: every phase's end conditions too).",
    )
    reached_end: bool = Field(..., description="The propagation reached the trajectory's end.")
    integrator: Integrator
    tolerances: VerificationTolerances
    final_state: StateValues = Field(..., description="Propagated final state (SI, degrees).")
    terminal_error_vs_target: dict[str, TerminalCheck] = Field(
        default_factory=dict, description="Per constrained state: the miss of its target."
    )
    terminal_error_vs_optimized: StateValues = Field(
        ..., description="Propagated minus optimized final state (SI, degrees)."
    )
    max_deviation_along_path: StateValues = Field(
        ..., description="Largest |propagated - optimized| at the nodes (SI, degrees)."
    )
    path_maxima: PathMaxima
    no_fly_zones: list[ZoneClearance] = Field(default_factory=list)
    control_limits: ControlPeaks = Field(
        default_factory=ControlPeaks,
        description="The flown bank (and bank rate) on the dense grid against the problem's "
        "control limits: a method bounds them at the nodes, the flight between them too.",
    )
    heat_load_J_m2: Number = Field(
        None, description="Integrated heat rate of the propagation, J/m^2 (null: no heat model)."
    )
    waypoints: list[WaypointPass] = Field(
        default_factory=list,
        description="Only with waypoints: each one's closest approach on the flown path, in "
        "order (the result is feasible only when every one is passed).",
    )
    propagated: PropagatedPath | None = Field(
        None,
        description="The propagated flight between and at the nodes (what the checks read), "
        "as columns.",
    )
    phases: list[PhaseCheck] = Field(
        default_factory=list,
        description="Only for a flight in phases: each phase's propagated end against its end "
        "conditions, in order (the last one's are also terminal_error_vs_target); a phase "
        "the propagation never entered (the ground came first) is absent.",
    )


class Software(_Record):
    """This project as it ran the solve."""

    name: str = Field(..., description="The distribution's name (entry-trajopt).")
    version: str | None = Field(None, description="Its installed version (null: not installed).")
    revision: str | None = Field(
        None,
        description="The git commit it ran from, with -dirty when the checkout had uncommitted "
        "changes; null when not run from a git checkout (an installed package).",
    )


class ScenarioOrigin(_Record):
    """A job submitted as a built-in scenario: the scenario and the patches applied to it."""

    name: str = Field(..., description="The built-in scenario (GET /v1/scenarios/{name}).")
    overrides: dict[str, Any] = Field(
        default_factory=dict,
        description="The request's overrides (a JSON Merge Patch of the scenario's problem), as "
        "submitted (for a batch's child: its base's).",
    )
    method: dict[str, Any] | None = Field(
        None, description="The request's method patch, applied after the overrides (null: none)."
    )


class AutoSelection(_Record):
    """How auto chose: the methods that accept the problem in its order, why each other
    method refused it, and why the result's method is the one kept."""

    chosen: str | None = Field(
        None, description="The method whose verified answer is kept (null: none succeeded)."
    )
    reason: str = Field(..., description="Why that method's answer is the result's.")
    rule: str = Field(..., description="The rule, in one line (docs/problem-contract.md).")
    candidates: list[str] = Field(
        default_factory=list, description="The methods that accept the problem, in auto's order."
    )
    refused: dict[str, list[str]] = Field(
        default_factory=dict,
        description="Each method that does not accept the problem: each reason, field first.",
    )


class Provenance(_Record):
    """What is needed to reproduce the result: the problem's fingerprint, where it came from,
    versions, options, platform, dynamics path."""

    created_at: str | None = Field(None, description="When the document was made (ISO 8601).")
    packages: dict[str, str | None] = Field(
        default_factory=dict,
        description="Installed version of each library whose version can change an answer "
        "(the numerical, solver, compiler, atmosphere and search libraries; null: absent).",
    )
    python: str | None = Field(None, description="Python version.")
    platform: str | None = Field(None, description="Operating system and machine.")
    method_options: dict[str, Any] = Field(
        default_factory=dict, description="The method's options as solved (defaults filled in)."
    )
    problem_name: str | None = Field(None, description="The problem document's name.")
    problem_sha256: str | None = Field(
        None,
        description="SHA-256 (hex) of the problem document as solved, in canonical JSON: keys "
        "sorted, no whitespace, as Python's json.dumps(problem, sort_keys=True, "
        "separators=(',', ':')) writes it, UTF-8 (docs/problem-contract.md, 'Problem "
        "fingerprint'). GET /v1/jobs/{id}/problem returns that document.",
    )
    source_job: str | None = Field(
        None,
        description="Only for a start from an earlier job's answer (initial_guess.from_job, or "
        "a chained batch's sibling): that job's id.",
    )
    scenario: ScenarioOrigin | None = Field(
        None,
        description="Only for a service job submitted as a built-in scenario: the scenario and "
        "the overrides and method patch it was submitted with.",
    )
    software: Software | None = Field(None, description="This project's version and revision.")
    dynamics: Literal["compiled", "numpy"] | None = Field(
        None,
        description="compiled: the model's equations of motion have a compiled form (used by "
        "the methods with compiled sweeps); numpy: they have none and run as numpy code, "
        "slower (dynamics_note says why).",
    )
    dynamics_note: str | None = Field(
        None, description="Why the dynamics have no compiled form (only with numpy)."
    )
    initial_guess: str | None = Field(
        None,
        description="Only for a given start: the trajectory the method started from (the "
        "problem's initial_guess) instead of its own guess, or how the global search that "
        "made it went (kind global).",
    )
    selection: AutoSelection | None = Field(
        None, description="Only for method auto: how it chose the result's method, and why."
    )


class StartSummary(_Record):
    """One start of a multi-start run (foh-ptr: the closest constant bank of each sign)."""

    start: int = Field(..., description="1-based, in the order run (1: the closest guess).")
    initial_bank_deg: Number = Field(None, description="Constant bank of the start's guess, deg.")
    status: str = Field(..., description="How the start's SCP ended (converged, failed, ...).")
    iterations: int = Field(..., description="Iterations the start ran.")
    objective_terms: dict[str, Number] = Field(
        default_factory=dict, description="Each objective term on the start's last iterate, SI."
    )
    chosen: bool = Field(..., description="Whether this start's answer is the result.")


class AutoAttempt(_Record):
    """One method run by auto (method ``auto``): what it did and what it found."""

    attempt: int = Field(..., description="1-based, in the order run.")
    method: str = Field(..., description="The method run.")
    purpose: Literal["answer", "cross_check"] = Field(
        ...,
        description="answer: tried for the answer (auto's order); cross_check: run after a "
        "success to compare its value.",
    )
    status: ResultStatus = Field(..., description="How its solve ended (verified or not).")
    failure_code: str | None = Field(None, description="Its failure code, when it failed.")
    failure_message: str | None = Field(None, description="Its failure message (own numbering).")
    iterations: int = Field(..., description="Its iterations (records of the history).")
    first_iteration: int | None = Field(
        None, description="Where its iterations start in the result's history (null: none)."
    )
    time_s: float = Field(..., description="Its whole solve with the verification, s.")
    objective: Number = Field(None, description="Its objective value (objective.units).")
    kept: bool = Field(..., description="Whether its answer is the result's.")
    start: str | None = Field(
        None, description="A cross-check of the same method: the other start it ran from."
    )
    options: dict[str, Any] = Field(
        default_factory=dict,
        description="The method's options as run (defaults filled in; time_limit_s what the "
        "run had left): submit these to run that method alone.",
    )


class CrossCheck(_Record):
    """Only for method auto with cross_check, or a named method's second start: the two
    verified values of one problem."""

    attempts: list[int] = Field(..., description="The attempts compared (attempts[].attempt).")
    methods: list[str] = Field(..., description="Their methods.")
    values: list[Number] = Field(..., description="Their objective values (objective.units).")
    relative_difference: Number = Field(
        None, description="|a - b| / max(|a|, |b|) (1); null when only one value exists."
    )
    agree: bool | None = Field(
        None, description="Whether they are within 0.5 % of each other (null: not compared)."
    )
    warning: str | None = Field(
        None,
        description="When they differ by more than 0.5 %: a local optimum is possible, and "
        "which value is kept (the better).",
    )
    note: str | None = Field(None, description="Why no comparison was made, when none was.")


class ResultDocument(_Record):
    """Trajectory with units, objective, verification, convergence history, timing, provenance."""

    schema_version: Literal["1.0"] = "1.0"
    status: ResultStatus = Field(
        ...,
        description="succeeded only when the SCP converged and the verification passed; "
        "failed, cancelled or timed_out otherwise, with failure.",
    )
    failure: Failure | None = None
    method: str = Field(
        ...,
        description="The method that solved the problem; for auto, the method whose answer is "
        "kept (or, when none succeeded, whose failure says most; provenance.selection says "
        "why).",
    )
    objective: ObjectiveValue | None = None
    trajectory: Trajectory | None = Field(
        None,
        description="The optimizer's nodes; absent when the solve produced none or its last "
        "iterate held non-finite values (failure says where).",
    )
    verification: Verification | None = Field(
        None,
        description="Propagation of the optimized controls through the nonlinear dynamics and "
        "the checks on it; null when it was stopped, absent without a trajectory.",
    )
    history: list[HistoryRecord] = Field(
        default_factory=list, description="Every SCP iteration of the attempt, in order."
    )
    starts: list[StartSummary] | None = Field(
        None,
        description="Each start of a multi-start run and which was kept (the best converged); "
        "absent for a single start. The history holds every start's iterations.",
    )
    attempts: list[AutoAttempt] | None = Field(
        None,
        description="For method auto: every method it ran, in order (for a named method with a "
        "second start: both runs), with its status, "
        "reason, iterations, time and value; the history holds each one's iterations.",
    )
    cross_check: CrossCheck | None = Field(
        None,
        description="For method auto with cross_check, or a named method's second start: the "
        "two values compared.",
    )
    timing: Timing
    provenance: Provenance = Field(default_factory=Provenance)
    warnings: list[PlausibilityWarning] = Field(
        default_factory=list,
        description="Legal values of the problem far outside what entry vehicles fly (likely "
        "slips of units); a failed result's advice names them first.",
    )
