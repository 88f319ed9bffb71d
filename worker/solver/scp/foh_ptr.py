"""Time-domain SCP with exact FOH discretization and an adaptive grid (paper 002, Algorithm 1).

Loop: discretize the bank-state dynamics exactly about the reference on its current grid
(transcription.foh_exact, Theorem 1 / eq. 24; or the trapezoidal rule for comparison), linearize
the log path limits (eq. 25-26) and the no-fly zones (eq. 27), at the nodes and between them,
solve Problem 2 (a QP) with the penalized trust region and, by default, the Lagrangian curvature
of the interval maps (an SQP step; transcription.foh_hessian), take its solution as the next
reference, and stop when no node, bank angle or interval length moved more than its tolerance
and the objective has settled.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from worker.solver import side_thread
from worker.solver.conic import ConicBackend, ConicStatus, make_backend
from worker.solver.constraints.between_nodes import stack_rows
from worker.solver.constraints.log_path import active_limits, inner_path_rows, path_rows_at
from worker.solver.constraints.no_fly import (
    inner_zone_rows,
    longitude_factor,
    penalty_window,
    zone_distance,
)
from worker.solver.constraints.path_compiled import limit_parameters
from worker.solver.dynamics_bank_state import NZ
from worker.solver.dynamics_compiled import compiled_parameters, warm_up
from worker.solver.method_result import MethodStatus as ScpStatus
from worker.solver.problem import STATE_NAMES, EntryProblem
from worker.solver.scp.foh_objective import TimeObjective
from worker.solver.scp.history import IterationRecord
from worker.solver.transcription.foh_exact import IntervalMaps, foh_exact
from worker.solver.transcription.foh_hessian import BlockLayout, convexified_curvature
from worker.solver.transcription.foh_subproblem import (
    FohSubproblem,
    GridLimits,
    SubproblemData,
    TerminalRow,
)
from worker.solver.transcription.time_grid import InitialGuessError, initial_reference
from worker.solver.transcription.time_trapezoid import trapezoid_maps
from worker.solver.verification import OptimizedTrajectory

Array = np.ndarray

STATE_KEYS = STATE_NAMES  # the terminal conditions, in time-form state order
DIFFERENCE_STEP = 1e-5
"""Step of the Hessian's forward differences in scaled subproblem units (1 cm of altitude, about
0.02 m/s of speed): truncation error ~1e-5 relative, rounding ~1e-11."""


def state_scale(problem: EntryProblem) -> Array:
    """Unit of each scaled state deviation: 1 km, 0.5 deg, 0.5 deg, 50 m/s, 0.5 deg, 1 deg, 5 deg.

    Roughly one late-iteration step of each state, so the trust region treats them alike.
    """
    sc = problem.scales
    d = math.radians
    return np.array(
        [1e3 / sc.radius_m, d(0.5), d(0.5), 50.0 / sc.speed_m_s, d(0.5), d(1.0), d(5.0)]
    )


@dataclass
class FohOutcome:
    """What the loop produced: final nodes, rates, interval lengths, status and history."""

    status: ScpStatus
    z: Array
    w: Array
    s: Array
    history: list[IterationRecord]
    failure_code: str | None = None
    failure_message: str | None = None
    conic_solve_s: float = 0.0
    objective_terms: dict[str, float] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)


def _terminal_rows(problem: EntryProblem, scale: Array, weight_virtual: float) -> list[TerminalRow]:
    """Terminal rows; fixed conditions get an L1-penalized buffer (virtual control, PTR) so an
    early linearization that cannot reach them in one step stays feasible."""
    rows = []
    for j, key in enumerate(STATE_KEYS):
        t = problem.terminal[key]
        if t.kind == "fixed":
            rows.append(
                TerminalRow(
                    j,
                    "soft",
                    value=float(t.value or 0.0),
                    weight=weight_virtual / scale[j],
                    virtual=True,
                )
            )
        elif t.kind == "soft":
            rows.append(TerminalRow(j, "soft", value=float(t.value or 0.0), weight=t.weight))
        elif t.kind == "range":
            rows.append(TerminalRow(j, "range", lo=float(t.lo or 0.0), hi=float(t.hi or 0.0)))
    return rows


def _tolerances(options: Any, problem: EntryProblem) -> tuple[Array, float]:
    """Stop tolerances on the 7 states (nondimensional) and on the interval lengths."""
    tol = options.stop_tolerance
    sc = problem.scales
    d = math.radians
    states = np.array(
        [
            tol.altitude_m / sc.radius_m,
            d(tol.longitude_deg),
            d(tol.latitude_deg),
            tol.velocity_m_s / sc.speed_m_s,
            d(tol.flight_path_angle_deg),
            d(tol.heading_deg),
            d(tol.bank_deg),
        ]
    )
    return states, tol.interval_s / sc.time_s


def _state_change(m: Array, problem: EntryProblem) -> dict[str, float]:
    """Largest change of each state (nondimensional ``m``) in SI units and degrees."""
    sc = problem.scales
    return {
        "altitude_m": float(m[0] * sc.radius_m),
        "longitude_deg": math.degrees(m[1]),
        "latitude_deg": math.degrees(m[2]),
        "velocity_m_s": float(m[3] * sc.speed_m_s),
        "flight_path_angle_deg": math.degrees(m[4]),
        "heading_deg": math.degrees(m[5]),
        "bank_deg": math.degrees(m[6]),
    }


class _Linearizer:
    """Builds the per-iteration ``SubproblemData`` (maps, path rows, zone rows, costs)."""

    def __init__(self, problem: EntryProblem, options: Any, scale: Array) -> None:
        self.problem = problem
        self.options = options
        self.scale = scale
        self.limits = active_limits(problem)
        self.zones = problem.no_fly_zones
        self.margin = 0.0
        fixed_bank = problem.document.initial_state.bank_deg
        self.initial = (
            np.r_[problem.y0, math.radians(fixed_bank)]
            if fixed_bank is not None
            else (problem.y0.copy())
        )
        self.objective: TimeObjective | None = None
        self.windows: list[list[int]] = []
        self.zone_clearance: list[float] = []
        self.inner_on = bool(
            options.intersample_constraints
            and options.discretization == "exact_foh"
            and options.foh_substeps > 1
            and (self.limits or self.zones)
        )
        self.inner_ratio = np.zeros(len(self.limits))
        self.path_parameters = limit_parameters(problem, self.limits)  # None: numpy rows
        self.second_order = bool(options.second_order)  # the schema allows it with exact_foh only
        self.difference_steps: Array | None = None  # set once the subproblem's scales are known
        self.layout: BlockLayout | None = None  # where the curvature goes in the subproblem's P

    def maps(self, z: Array, w: Array, s: Array) -> IntervalMaps:
        p, o = self.problem, self.options
        if o.discretization == "trapezoid":
            return trapezoid_maps(z, w, s, p.forces, p.omega)
        return foh_exact(z, w, s, p.forces, p.omega, o.foh_substeps, samples=self.inner_on)

    def curvature(self, z: Array, w: Array, s: Array, multipliers: Array | None) -> Array | None:
        """The P entries of the convexified Lagrangian curvature of the interval maps about the
        reference (z, w, s) (``foh_hessian.convexified_curvature``), or None.

        ``multipliers`` (N, 7): the last subproblem's multipliers of the dynamics rows, in
        nondimensional state units. None without them, without ``second_order``, or when a
        perturbed integration is not finite (the step is then first-order).
        """
        if multipliers is None or not self.second_order or self.layout is None:
            return None
        assert self.difference_steps is not None
        p = self.problem
        return convexified_curvature(
            z,
            w,
            s,
            p.forces,
            p.omega,
            -multipliers,  # the rows read x_{k+1} - Phi_k(v_k): Phi_k enters with a minus
            self.difference_steps,
            self.options.second_order_substeps,
            self.layout,
        )

    def report(self) -> dict[str, Any]:
        """The last linearization's between-node path ratios and zone clearances, for the
        history (``IterationRecord.extra``)."""
        between = (
            {name: float(self.inner_ratio[j]) for j, name in enumerate(self.limits)}
            if self.inner_on and self.limits
            else {}
        )
        return {
            "path_ratio_between_nodes": between,
            "no_fly_zone_clearance_deg": list(self.zone_clearance),
            "no_fly_zone_window_nodes": [list(wd) for wd in self.windows],
        }

    def data(self, z: Array, w: Array, s: Array) -> tuple[SubproblemData, Array]:
        """Subproblem data about (z, w, s), without the curvature (``curvature``), and the
        path-limit ratios at the nodes (K, m)."""
        p, o = self.problem, self.options
        k = z.shape[0]
        mp = self.maps(z, w, s)
        inner = None
        if self.inner_on:
            samples = mp.samples
            assert samples is not None
            n, j = samples.x.shape[:2]
            # one evaluation at every sample and the last node: sample 0 of interval k is node k
            r = np.concatenate([samples.x[..., 0].ravel(), z[-1:, 0]])
            v = np.concatenate([samples.x[..., 3].ravel(), z[-1:, 3]])
            at_samples = path_rows_at(p, r, v, self.path_parameters)
            rows = at_samples.take(np.arange(0, n * j + 1, j))  # sample 0s, then the last node
            parts = []
            if self.limits:
                parts.append(inner_path_rows(at_samples.take(slice(0, n * j)), samples))
                self.inner_ratio = np.exp(np.max(parts[0].worst, axis=0))
            if self.zones:
                parts.append(inner_zone_rows(self.zones, samples, self.margin))
            inner = stack_rows(parts)
        else:
            rows = path_rows_at(p, z[:, 0], z[:, 3], self.path_parameters)
        if self.objective is None:
            self.objective = TimeObjective(p, self.scale, z, s)
        grad_z, grad_s = self.objective.gradients(z, s)
        quad = np.zeros((k, NZ))
        quad_c = np.zeros((k, NZ))
        if rows.names and o.weight_nonlinear > 0:
            quad[:, 3] = o.weight_nonlinear / z[:, 3] ** 2  # eq. 26: (V - V_bar)^2 / V_bar^2
            quad_c[:, 3] = z[:, 3]
        nzone = len(self.zones)
        zc = np.zeros((nzone, k))
        zlat = np.zeros((nzone, k))
        zlon = np.zeros((nzone, k))
        weighted_c = np.zeros((k, NZ))
        self.windows = []
        self.zone_clearance = []
        for i, zone in enumerate(self.zones):
            rows_z = zone_distance(z[:, 2], z[:, 1], zone)
            clearance = rows_z.c - zone.radius
            zc[i] = clearance - self.margin
            zlat[i] = rows_z.c_lat
            zlon[i] = rows_z.c_lon
            self.zone_clearance.append(math.degrees(float(np.min(clearance))))
            engaged = float(np.min(clearance)) <= math.radians(o.no_fly_zone_engage_deg)
            if engaged and o.weight_no_fly_zone > 0:
                mask = penalty_window(clearance, o.no_fly_zone_window)
                self.windows.append([int(j) for j in np.flatnonzero(mask)])
                wz = o.weight_no_fly_zone / zone.radius**2
                coslat = longitude_factor(zone)
                quad[mask, 2] += wz
                weighted_c[mask, 2] += wz * zone.latitude
                quad[mask, 1] += wz * coslat**2
                weighted_c[mask, 1] += wz * coslat**2 * zone.longitude
            else:
                self.windows.append([])
        if any(self.windows):  # an engaged zone pulls its window toward its centre
            for j in (1, 2):
                on = quad[:, j] > 0
                quad_c[on, j] = weighted_c[on, j] / quad[on, j]
        data = SubproblemData(
            z=z,
            w=w,
            s=s,
            maps=mp,
            initial=self.initial,
            path_g=rows.g,
            path_gr=rows.g_r,
            path_gv=rows.g_v,
            zone_c=zc,
            zone_clat=zlat,
            zone_clon=zlon,
            grad_z=grad_z,
            grad_s=grad_s,
            quad_z=quad,
            quad_center=quad_c,
            inner=inner,
        )
        return data, rows.ratio


def _finite(data: SubproblemData) -> bool:
    """Whether the linearization is usable (a long step can leave the atmosphere model)."""
    mp = data.maps
    parts = [mp.x_prop, mp.jacobian, data.path_g]
    if data.inner is not None:
        parts.append(data.inner.g)
    return all(bool(np.all(np.isfinite(a))) for a in parts)


def _defect(data: SubproblemData, scale: Array) -> tuple[Array, float]:
    """How far the reference nodes are from their own propagation: the largest gap per state
    (nondimensional) and overall in scaled units. It judges the step that made the reference."""
    by_state = np.max(np.abs(data.maps.x_prop - data.z[1:]), axis=0)
    return by_state, float(np.max(by_state / scale))


def _adapt_trust_weight(w_tr: float, defect: float, options: Any) -> float:
    """Scale w_tr by sqrt(defect / target), within trust_factor either way: a step's defect grows
    about as the square of its length, and its length as 1 / w_tr (paper 002 keeps w_tr fixed)."""
    factor = math.sqrt(max(defect, 1e-12) / options.trust_defect_target)
    factor = min(max(factor, 1.0 / options.trust_factor), options.trust_factor)
    return min(max(w_tr * factor, options.weight_trust_region_min), 1e3)


def _cosine(a: Array, b: Array) -> float:
    """Cosine of the angle between two steps (0 when either is zero)."""
    norm = float(np.linalg.norm(a) * np.linalg.norm(b))
    return float(np.dot(a, b)) / norm if norm > 0.0 else 0.0


@dataclass
class _Proposal:
    """A solved subproblem whose step is judged at the next reference, once its defect is known."""

    record: IterationRecord
    weight_trust_region: float
    small: bool
    virtual: float
    cost: float
    values: dict[str, float]
    reversal: float  # cosine between this step and the one before (-1: straight back)


def run_foh_ptr(
    problem: EntryProblem,
    options: Any,
    *,
    on_iteration: Callable[[IterationRecord], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
    backend: ConicBackend | None = None,
) -> FohOutcome:
    """Run paper 002's SCP on ``problem`` (fixed final time) with the method ``options``.

    Each iteration solves one subproblem about the current reference; its solution becomes the next
    reference, whose discretization also gives the step's defect (nodes minus their propagation).
    The defect adapts the trust weight w_tr (paper 002 keeps it fixed), a step that swings back
    grows it, and convergence is declared only when the step was small, its defect is within the
    stop tolerance and w_tr is not above its initial value (a step kept small by a heavy trust
    weight is not a converged one). The subproblem's multipliers of the dynamics rows feed the
    next iteration's curvature term.
    """
    if compiled_parameters(problem.forces, problem.omega) is not None:
        warm_up()  # compile or load the kernels before the clock starts (at once when loaded)
    start = time.perf_counter()
    if problem.final_time is None:
        raise ValueError("foh-ptr needs a fixed final time")
    sc = problem.scales
    nodes = options.nodes
    scale = state_scale(problem)
    try:
        ref = initial_reference(problem, nodes, options.initial_bank_deg)
    except InitialGuessError as exc:  # the method cannot start: a failed job, not an error
        empty = np.zeros(0)
        return FohOutcome("failed", np.zeros((0, NZ)), empty, empty, [], "initial_guess", str(exc))
    z, w, s = ref.z, ref.w, ref.s
    adaptive = options.grid == "adaptive"
    grid = (
        GridLimits(
            delta_min=options.interval_min_s / sc.time_s,
            delta_max=options.interval_max_s / sc.time_s,
            delta_trust=options.interval_trust_s / sc.time_s,
            final_time=problem.final_time,
        )
        if adaptive
        else None
    )
    lin = _Linearizer(problem, options, scale)
    sub = FohSubproblem(
        nodes,
        state_scale=scale,
        rate_scale=math.radians(1.0) * sc.time_s,
        interval_scale=10.0 / sc.time_s,
        n_initial=lin.initial.size,
        terminal=_terminal_rows(problem, scale, options.weight_virtual_control),
        bank_max=problem.bank_max,
        bank_rate_max=problem.bank_rate_max,
        n_limits=len(lin.limits),
        n_zones=len(problem.no_fly_zones),
        grid=grid,
        n_inner_rows=len(lin.limits) + len(problem.no_fly_zones) if lin.inner_on else 0,
        weight_trust_region=options.weight_trust_region,
        weight_trust_interval=options.weight_trust_interval,
        weight_buffer=options.weight_virtual_control,
        hessian_blocks=lin.second_order,
        identity_e=options.discretization == "exact_foh",
    )
    lin.difference_steps = DIFFERENCE_STEP * sub.block_scale
    lin.layout = sub.curvature_layout
    backend = backend or make_backend(options.conic_backend, fallback=options.fallback_solver)
    tol_z, tol_s = _tolerances(options, problem)
    history: list[IterationRecord] = []
    conic_total = 0.0
    deadline = start + options.time_limit_s
    prev_cost: float | None = None
    w_tr = options.weight_trust_region
    values: dict[str, float] = {}
    extra: dict[str, Any] = {"initial_bank_deg": ref.bank_deg}
    pending: _Proposal | None = None
    it_start = time.perf_counter()
    last_multipliers: Array | None = None
    last_step: Array | None = None
    virtual = np.array([t.virtual for t in sub.soft], dtype=bool)  # terminal buffers
    soft_weights = np.array([t.weight for t in sub.soft if not t.virtual])
    virtual_unit = 1.0 / scale[[t.state for t in sub.soft if t.virtual]]

    # The curvature of a new reference needs only the reference and the multipliers: with a
    # second CPU it is integrated and convexified on the helper thread while this one
    # discretizes the same reference (the kernels release the GIL); otherwise, in line once
    # the loop goes on.
    overlap = lin.second_order and side_thread.available()
    curvature: Future[Array | None] | None = None

    data, ratio = lin.data(z, w, s)
    defect_by_state, defect = _defect(data, scale)

    def outcome(status: ScpStatus, code: str | None = None, msg: str | None = None) -> FohOutcome:
        return FohOutcome(status, z, w, s, history, code, msg, conic_total, values, extra)

    def emit(record: IterationRecord) -> None:
        history.append(record)
        if on_iteration is not None:
            on_iteration(record)

    it = 0
    while True:
        converged = False
        if pending is not None:  # judge the last step at its own reference
            if pending.reversal < -options.trust_reversal_cosine:  # the iterates swing back
                w_tr = min(pending.weight_trust_region * options.trust_factor, 1e3)
            else:
                w_tr = _adapt_trust_weight(w_tr, defect, options)
            pending.record.extra["step_defect"] = defect
            emit(pending.record)
            values = pending.values
            settled = prev_cost is not None and abs(pending.cost - prev_cost) <= (
                options.stop_tolerance.relative_cost * max(abs(pending.cost), 1.0)
            )
            prev_cost = pending.cost
            converged = (
                pending.small
                and settled
                and pending.virtual <= 1e-6
                and pending.weight_trust_region <= options.weight_trust_region
                and bool(np.all(defect_by_state <= tol_z))
            )
            pending = None
        if converged:
            return outcome("converged")
        if it >= options.max_iterations:
            return outcome(
                "max_iterations",
                "max_iterations",
                f"not converged in {options.max_iterations} iterations",
            )
        it += 1
        if should_stop is not None and should_stop():
            return outcome("cancelled", "cancelled", f"cancelled before iteration {it}")
        remaining = deadline - time.perf_counter()
        if remaining <= 0:
            return outcome(
                "timed_out",
                "time_limit",
                f"time limit {options.time_limit_s} s reached after {it - 1} iterations",
            )
        sub.set_virtual_factor(
            min(options.virtual_control_growth ** (it - 1), 1.0e6)
            * options.weight_virtual_control_initial
            / options.weight_virtual_control
            if options.weight_virtual_control_initial < options.weight_virtual_control
            else 1.0
        )
        if sub.w_buf > options.weight_virtual_control:
            sub.set_virtual_factor(1.0)
        sub.w_tr = w_tr
        if curvature is None:  # in line: one CPU, or a reference restored after a rejection
            curvature = side_thread.completed(lin.curvature(z, w, s, last_multipliers))
        subproblem = sub.build(data, curvature.result)  # waits for the curvature last
        second_order = curvature.result() is not None
        curvature = None
        lin_s = time.perf_counter() - it_start
        limit = (
            remaining
            if options.conic_time_limit_s is None
            else min(remaining, options.conic_time_limit_s)
        )
        sol = backend.solve(subproblem, time_limit_s=limit)
        conic_total += sol.solve_time_s
        if not sol.status.usable or sol.x is None:
            code = {
                ConicStatus.INFEASIBLE: "infeasible",
                ConicStatus.TIME_LIMIT: "time_limit",
            }.get(sol.status, "numerical_error")
            status: ScpStatus = "timed_out" if code == "time_limit" else "failed"
            return outcome(
                status,
                code,
                f"iteration {it}: convex subproblem {sol.status.value} "
                f"({sol.solver}: {sol.raw_status})",
            )
        multipliers = (
            sol.y[: sub.N * NZ].reshape(sub.N, NZ) / scale  # the rows are divided by the scale
            if lin.second_order and sol.y is not None
            else None
        )
        new = sub.unpack(sol.x, data)
        if overlap and multipliers is not None:  # the new reference's curvature, on the helper
            curvature = side_thread.submit(lin.curvature, new.z, new.w, new.s, multipliers)
        made_by, made_by_ratio, made_by_report = data, ratio, lin.report()
        data, ratio = lin.data(new.z, new.w, new.s)  # the next linearization judges this step
        change = np.max(np.abs(new.z - z), axis=0)
        change_s = float(np.max(np.abs(new.s - s))) if s.size else 0.0
        assert lin.objective is not None
        new_values = lin.objective.values(new.z, new.s)
        cost = lin.objective.normalized(new_values)
        step = np.concatenate([new.dz.ravel(), new.dw])
        tr_slack = float(np.dot(step, step))
        reversal = _cosine(step, last_step) if last_step is not None else 0.0
        quad, center = made_by.quad_z, made_by.quad_center
        nl_pen = float(np.sum(quad[:, 3] * (new.z[:, 3] - z[:, 3]) ** 2))
        zone_pen = float(np.sum(quad[:, 1:3] * (new.z[:, 1:3] - center[:, 1:3]) ** 2))
        soft = float(np.dot(soft_weights, new.soft_slacks[~virtual]))
        vc_norm = float(np.sum(new.soft_slacks[virtual] * virtual_unit) + np.sum(new.buffers))
        t_nodes = np.concatenate([[0.0], np.cumsum(new.s)]) * sc.time_s
        record = IterationRecord(
            iteration=it,
            cost=float(sol.objective if sol.objective is not None else np.nan),
            cost_terms={
                **{f"objective:{n}": v for n, v in new_values.items()},
                "trust_region": w_tr * tr_slack,
                "trust_interval": options.weight_trust_interval * float(np.sum(new.ds**2)),
                "nonlinear_path": nl_pen,
                "no_fly_zone": zone_pen,
                "soft_terminal": soft,
                "virtual_control": options.weight_virtual_control * vc_norm,
            },
            objective_value=next(iter(new_values.values())) if len(new_values) == 1 else None,
            max_state_change=_state_change(change, problem),
            trust_region_slack=tr_slack,
            virtual_control_norm=vc_norm,
            linearization_error=float(defect),
            nodes_post_corrected=0,
            relaxation_gap=0.0,
            conic_status=sol.status.value,
            conic_solver=sol.solver,
            conic_solve_s=sol.solve_time_s,
            conic_setup_s=sol.setup_time_s,
            conic_solver_setup_s=sol.clarabel_setup_s,
            iteration_wall_s=0.0,
            extra={
                "max_interval_change_s": change_s * sc.time_s,
                "interval_s_min": float(np.min(new.s) * sc.time_s),
                "interval_s_max": float(np.max(new.s) * sc.time_s),
                "path_ratio_at_nodes": {
                    name: float(np.max(made_by_ratio[:, j])) for j, name in enumerate(lin.limits)
                },
                **made_by_report,
                "discretization_s": lin_s,
                "second_order_step": second_order,
                "weight_trust_region": w_tr,
                "node_times_s": t_nodes.tolist(),
            },
        )
        pending = _Proposal(
            record=record,
            weight_trust_region=w_tr,
            small=bool(np.all(change <= tol_z) and change_s <= tol_s),
            virtual=vc_norm,
            cost=cost,
            values=new_values,
            reversal=reversal,
        )
        previous = (z, w, s, last_multipliers)
        z, w, s, last_multipliers = new.z, new.w, new.s, multipliers
        if not _finite(data):  # reject the step: back to the reference, heavier trust weight
            curvature = None  # of the rejected reference: not used
            z, w, s, last_multipliers = previous
            data, ratio = lin.data(z, w, s)
            w_tr = min(w_tr * options.trust_factor, 1e3)
            record.extra["rejected"] = "the step's propagation left the models' range"
            record.iteration_wall_s = time.perf_counter() - it_start
            it_start = time.perf_counter()
            emit(record)
            pending = None
            continue
        last_step = step
        defect_by_state, defect = _defect(data, scale)
        record.iteration_wall_s = time.perf_counter() - it_start
        it_start = time.perf_counter()


def to_trajectory(problem: EntryProblem, outcome: FohOutcome) -> OptimizedTrajectory:
    """The nodes as a time-grid trajectory, with the FOH bank rate for exact bank propagation."""
    t = np.concatenate([[0.0], np.cumsum(outcome.s)])
    return OptimizedTrajectory(
        "time",
        t,
        outcome.z[:, : NZ - 1].copy(),
        t,
        outcome.z[:, NZ - 1].copy(),
        bank_rate=outcome.w.copy(),
    )
