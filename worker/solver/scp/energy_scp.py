"""Energy-domain SCP with post-correction (paper 000, Jung, Kim, Choi & Lee).

Loop (paper 000 sec. 3.4, steps 1-4): linearize the energy-form dynamics about the reference,
solve the trapezoidal SOCP (transcription.energy_trapezoid), shorten the step of every
(node, state) whose linearization error is large (post-correction), and stop when no state moved
more than its tolerance (eq. 37). Departures from the printed method, each a correction:
the exact V(r, e) replaces eq. 8's approximation; the trust region is scaled per state; virtual
control is added only when a subproblem is infeasible, and then penalized and reported.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from worker.solver.conic import ConicBackend, ConicStatus, make_backend
from worker.solver.dynamics import (
    EnergyDerivatives,
    EnergyRates,
    energy_dynamics,
    energy_rates,
    time_state_from_energy,
)
from worker.solver.method_result import MethodStatus as ScpStatus
from worker.solver.objectives import (
    RUNNING_COSTS,
    TERMINAL_COSTS,
    RunningCost,
    energy_running_cost,
    energy_running_density,
    trapezoid,
)
from worker.solver.path_limits import radius_lower_bound
from worker.solver.problem import EntryProblem
from worker.solver.scp.history import IterationRecord
from worker.solver.transcription.energy_grid import energy_grid, time_uniform_grid
from worker.solver.transcription.energy_trapezoid import (
    NX,
    EnergyTrapezoid,
    SubproblemData,
    TerminalRow,
)
from worker.solver.verification import OptimizedTrajectory

Array = np.ndarray

# Scale of each energy-form state [r, theta, phi, gamma, psi]: the unit of the scaled deviation
# in the subproblem and so of the trust region (6.4 km in radius, 1 deg in the angles, 0.5 deg
# in flight-path angle, which moves least).
STATE_SCALE = np.array(
    [1.0e-3, math.radians(1.0), math.radians(1.0), math.radians(0.5), math.radians(1.0)]
)
REGRID_AFTER = 2
TERMINAL_KEYS = (
    "altitude_m",
    "longitude_deg",
    "latitude_deg",
    "flight_path_angle_deg",
    "heading_deg",
)


@dataclass
class ScpOutcome:
    """What the loop produced: the final nodes, its status and the history."""

    status: ScpStatus
    e: Array
    x: Array
    u: Array
    history: list[IterationRecord]
    failure_code: str | None = None
    failure_message: str | None = None
    conic_solve_s: float = 0.0
    virtual_control_used: bool = False
    extra: dict[str, Any] = field(default_factory=dict)


def energy_bounds(problem: EntryProblem) -> tuple[float, float]:
    """Initial energy from the initial state; final from the document or terminal altitude+speed."""
    y0 = problem.y0
    e0 = 1.0 / y0[0] - 0.5 * y0[3] ** 2
    if problem.energy_final is not None:
        return e0, problem.energy_final
    alt = problem.terminal["altitude_m"]
    vel = problem.terminal["velocity_m_s"]
    if alt.kind != "fixed" or vel.kind != "fixed" or alt.value is None or vel.value is None:
        raise ValueError(
            "the final energy needs energy.final or a fixed terminal altitude and speed"
        )
    return e0, 1.0 / alt.value - 0.5 * vel.value**2


def _terminal_rows(problem: EntryProblem) -> list[TerminalRow]:
    rows = []
    for j, key in enumerate(TERMINAL_KEYS):
        t = problem.terminal[key]
        if t.kind == "fixed":
            rows.append(TerminalRow(j, "fixed", value=float(t.value or 0.0)))
        elif t.kind == "soft":
            rows.append(TerminalRow(j, "soft", value=float(t.value or 0.0), weight=t.weight))
        elif t.kind == "range":
            rows.append(TerminalRow(j, "range", lo=float(t.lo or 0.0), hi=float(t.hi or 0.0)))
    return rows


def initial_guess(problem: EntryProblem, e: Array) -> tuple[Array, Array]:
    """Straight line from initial to terminal state in energy, zero control (paper 000 sec. 4)."""
    x0 = problem.y0[[0, 1, 2, 4, 5]]
    xf = x0.copy()
    for j, key in enumerate(TERMINAL_KEYS):
        target = problem.terminal[key].target()
        if target is not None:
            xf[j] = target
    s = (e - e[0]) / (e[-1] - e[0])
    x = x0[None, :] + s[:, None] * (xf - x0)[None, :]
    return x, np.zeros((e.size, 2))


class _Objective:
    """The problem's objective terms, normalized so that each is O(1) on the initial guess.

    A running cost is evaluated once per linearization ``ed`` (the last one is kept).
    """

    def __init__(self, problem: EntryProblem, e: Array, x: Array, ed: EnergyDerivatives) -> None:
        self.problem = problem
        self.e = e
        self.scale: dict[str, float] = {}
        self._cached_ed: EnergyDerivatives | None = None
        self._cached: dict[str, RunningCost] = {}
        for term in problem.objective:
            if term.name in RUNNING_COSTS:
                value = trapezoid(self._running(term.name, x, ed).density, e)
                self.scale[term.name] = abs(value) if value != 0 else 1.0
            else:
                self.scale[term.name] = 1.0

    def _running(self, name: str, x: Array, ed: EnergyDerivatives) -> RunningCost:
        """Running cost ``name`` on ``x`` (``ed`` is the dynamics at ``x``), cached per ``ed``."""
        if ed is not self._cached_ed:
            self._cached_ed = ed
            self._cached = {}
        cost = self._cached.get(name)
        if cost is None:
            cost = self._cached[name] = energy_running_cost(self.problem, name, x, ed)
        return cost

    def gradients(self, x: Array, ed: EnergyDerivatives) -> tuple[Array, Array]:
        """Running-cost gradient per unit energy (K, 5) and terminal gradient (5,), normalized."""
        run = np.zeros_like(x)
        term = np.zeros(NX)
        for t in self.problem.objective:
            w = t.weight / self.scale[t.name]
            if t.name in RUNNING_COSTS:
                run += w * self._running(t.name, x, ed).gradient
            else:
                idx, sign = TERMINAL_COSTS[t.name]
                term[idx] += w * sign
        return run, term

    def values(self, x: Array, rates: EnergyRates) -> dict[str, float]:
        """Each term's value in SI units (J/m^2, s, deg) on trajectory x (``rates`` at x)."""
        out: dict[str, float] = {}
        for t in self.problem.objective:
            if t.name in RUNNING_COSTS:
                density = energy_running_density(self.problem, t.name, x, rates)
                out[t.name] = trapezoid(density, self.e)
            else:
                idx, _ = TERMINAL_COSTS[t.name]
                out[t.name] = math.degrees(float(x[-1, idx]))
        return out


def _state_change(m: Array, problem: EntryProblem) -> dict[str, float]:
    """The largest change of each state (``m``, energy-form units) in the reported units."""
    return {
        "altitude_m": float(m[0] * problem.scales.radius_m),
        "longitude_deg": math.degrees(m[1]),
        "latitude_deg": math.degrees(m[2]),
        "flight_path_angle_deg": math.degrees(m[3]),
        "heading_deg": math.degrees(m[4]),
    }


def _tolerance_vector(options: Any, problem: EntryProblem) -> Array:
    tol = options.stop_tolerance
    return np.array(
        [
            tol.altitude_m / problem.scales.radius_m,
            math.radians(tol.longitude_deg),
            math.radians(tol.latitude_deg),
            math.radians(tol.flight_path_angle_deg),
            math.radians(tol.heading_deg),
        ]
    )


def run_energy_scp(
    problem: EntryProblem,
    options: Any,
    *,
    on_iteration: Callable[[IterationRecord], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
    backend: ConicBackend | None = None,
) -> ScpOutcome:
    """Run paper 000's SCP on ``problem`` with the method ``options`` of the request."""
    start = time.perf_counter()
    e0, ef = energy_bounds(problem)
    e = energy_grid(e0, ef, options.nodes, "uniform" if options.grid == "uniform" else "glide_time")
    omega = problem.omega
    forces = problem.forces
    backend = backend or make_backend(options.conic_backend, fallback=options.fallback_solver)
    r_lower = None
    r_ceiling = 1.0 + 200e3 / problem.scales.radius_m
    regrid_done = 0
    if problem.limits.any:
        r_lower, feasible = radius_lower_bound(forces, problem.limits, e, 1.0, r_ceiling)
        if not np.all(feasible):
            bad = int(np.argmin(feasible))
            return ScpOutcome(
                "failed",
                e,
                *initial_guess(problem, e),
                [],
                failure_code="path_limits_infeasible",
                failure_message=(
                    f"no altitude satisfies the path limits at energy {e[bad]:.4f} "
                    f"(node {bad}); raise the limits or change the energy range"
                ),
            )
    terminal = _terminal_rows(problem)
    vc_mode = options.virtual_control
    use_vc = vc_mode == "on"

    def make_transcription(vc: bool) -> EnergyTrapezoid:
        return EnergyTrapezoid(
            e,
            STATE_SCALE,
            terminal,
            bank_max=problem.bank_max,
            path_limits=r_lower is not None,
            virtual_control=vc,
            weight_trust_region=options.weight_trust_region,
            weight_regularization=options.weight_regularization,
            weight_virtual_control=options.weight_virtual_control,
            weight_control_smoothness=options.weight_control_smoothness,
        )

    tr = make_transcription(use_vc)
    node_step = tr.quad_w
    x_ref, u_ref = initial_guess(problem, e)
    x0 = problem.y0[[0, 1, 2, 4, 5]]
    ed = energy_dynamics(x_ref, u_ref, e, forces, omega)
    objective = _Objective(problem, e, x_ref, ed)
    tol = _tolerance_vector(options, problem)
    history: list[IterationRecord] = []
    conic_total = 0.0
    x_sol, u_sol = x_ref, u_ref
    deadline = start + options.time_limit_s

    def outcome(
        status: ScpStatus, code: str | None = None, message: str | None = None
    ) -> ScpOutcome:
        return ScpOutcome(
            status, e, x_sol, u_sol, history, code, message, conic_total, tr.virtual_control
        )

    for k in range(1, options.max_iterations + 1):
        it_start = time.perf_counter()
        if should_stop is not None and should_stop():
            return outcome("cancelled", "cancelled", f"cancelled before iteration {k}")
        remaining = deadline - it_start
        if remaining <= 0:
            return outcome(
                "timed_out",
                "time_limit",
                f"time limit {options.time_limit_s} s reached after {k - 1} iterations",
            )
        run_grad, term_grad = objective.gradients(x_ref, ed)
        data = SubproblemData(
            x_ref=x_ref,
            u_ref=u_ref,
            f=ed.f,
            A=ed.A,
            B=ed.B,
            cost_gradient=run_grad,
            terminal_gradient=term_grad,
            radius_lower=r_lower,
            x0=x0,
        )
        # whole seconds (rounded down) above 2 s: the limit then rarely changes between
        # iterations, so the conic backend need not rebuild its settings; the loop itself checks
        # the deadline before every iteration
        budget = (
            remaining
            if options.conic_time_limit_s is None
            else min(remaining, options.conic_time_limit_s)
        )
        limit = math.floor(budget) if budget > 2.0 else budget
        sol = backend.solve(tr.build(data), time_limit_s=limit)
        conic_total += sol.solve_time_s
        if sol.status == ConicStatus.INFEASIBLE and vc_mode == "auto" and not tr.virtual_control:
            tr = make_transcription(True)
            sol2 = backend.solve(
                tr.build(data), time_limit_s=max(deadline - time.perf_counter(), 1e-3)
            )
            conic_total += sol2.solve_time_s
            sol = sol2
        if not sol.status.usable or sol.x is None:
            code = {
                ConicStatus.INFEASIBLE: "infeasible",
                ConicStatus.TIME_LIMIT: "time_limit",
            }.get(sol.status, "numerical_error")
            status: ScpStatus = "timed_out" if code == "time_limit" else "failed"
            return outcome(
                status,
                code,
                f"iteration {k}: conic subproblem {sol.status.value} "
                f"({sol.solver}: {sol.raw_status})",
            )
        z = sol.x
        sub = tr.unpack(z, data)
        # post-correction (paper 000 eq. 38 and the state update algorithm)
        # values only: the Jacobians are needed at the next reference x_next, below
        ed_new = energy_rates(sub.x, sub.u, e, forces, omega)
        f_lin = (
            ed.f
            + np.einsum("kij,kj->ki", ed.A, sub.x - x_ref)
            + np.einsum("kij,kj->ki", ed.B, sub.u - u_ref)
        )
        lin_err = np.abs(ed_new.f - f_lin) * node_step[:, None] / STATE_SCALE[None, :]
        corrected = np.zeros_like(lin_err, dtype=bool)
        x_next = sub.x
        if options.post_correction:
            corrected = lin_err > options.linearization_error_threshold
            corrected[0] = False
            x_next = np.where(
                corrected, x_ref + options.post_correction_step * (sub.x - x_ref), sub.x
            )
        dx = x_next - x_ref
        change = np.max(np.abs(dx), axis=0)
        x_sol, u_sol = sub.x, sub.u
        x_ref, u_ref = x_next, sub.u
        values = objective.values(sub.x, ed_new)
        vc_norm = (
            float(np.sum(np.abs(sub.virtual_control))) if sub.virtual_control is not None else 0.0
        )
        tr_slack = float(np.sum(sub.dx_scaled**2))
        record = IterationRecord(
            iteration=k,
            cost=(
                next(iter(values.values()))
                if len(values) == 1
                else sum(
                    t.weight * values[t.name] / objective.scale[t.name] for t in problem.objective
                )
            ),
            subproblem_cost=float(sol.objective if sol.objective is not None else np.nan),
            cost_terms={
                **{f"objective:{n}": v for n, v in values.items()},
                "soft_terminal": float(np.dot([t.weight for t in tr.soft], sub.soft_slacks))
                if tr.soft
                else 0.0,
                "trust_region": float(options.weight_trust_region * tr_slack),
                "virtual_control": options.weight_virtual_control * vc_norm
                if tr.virtual_control
                else 0.0,
            },
            objective_value=next(iter(values.values())) if len(values) == 1 else None,
            max_state_change=_state_change(change, problem),
            trust_region_slack=tr_slack,
            virtual_control_norm=vc_norm,
            linearization_error=float(np.max(lin_err)),
            nodes_post_corrected=int(np.count_nonzero(np.any(corrected, axis=1))),
            relaxation_gap=float(np.max(1.0 - np.linalg.norm(sub.u, axis=1))),
            conic_status=sol.status.value,
            conic_solver=sol.solver,
            conic_solve_s=sol.solve_time_s,
            conic_setup_s=sol.setup_time_s,
            conic_solver_setup_s=sol.clarabel_setup_s,
            iteration_wall_s=time.perf_counter() - it_start,
        )
        history.append(record)
        if on_iteration is not None:
            on_iteration(record)
        if np.all(change < tol) and vc_norm <= 1e-6 and k > regrid_done:
            return outcome("converged")
        if k == REGRID_AFTER and options.grid != "uniform":
            # re-space the nodes evenly in the iterate's flight time (resolves the terminal
            # maneuver, which a grid even in energy crowds into its last intervals)
            e_new = time_uniform_grid(e, 1.0 / energy_rates(x_ref, u_ref, e, forces, omega).edot)
            x_ref = np.column_stack([np.interp(e_new, e, x_ref[:, j]) for j in range(NX)])
            u_ref = np.column_stack([np.interp(e_new, e, u_ref[:, j]) for j in range(2)])
            e = e_new
            tr.set_grid(e)
            objective.e = e
            node_step = tr.quad_w
            if r_lower is not None:
                r_lower, _ = radius_lower_bound(forces, problem.limits, e, 1.0, r_ceiling)
            regrid_done = k + 1
            record.extra["regrid"] = True
        if k < options.max_iterations:  # linearize about the next reference
            ed = energy_dynamics(x_ref, u_ref, e, forces, omega)
    return outcome(
        "max_iterations", "max_iterations", f"not converged in {options.max_iterations} iterations"
    )


def to_trajectory(problem: EntryProblem, outcome: ScpOutcome) -> OptimizedTrajectory:
    """The nodes as a time-form trajectory: V from (r, e), time by the trapezoid of dt/de."""
    e, x, u = outcome.e, outcome.x, outcome.u
    ed = energy_dynamics(x, u, e, problem.forces, problem.omega)
    y, _ = time_state_from_energy(x, e)
    dt_de = 1.0 / ed.edot
    t = np.concatenate([[0.0], np.cumsum(0.5 * (dt_de[1:] + dt_de[:-1]) * np.diff(e))])
    bank = np.arctan2(u[:, 1], u[:, 0])
    return OptimizedTrajectory("energy", e, y, t, bank)
