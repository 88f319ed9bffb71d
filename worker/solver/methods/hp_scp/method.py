"""Paper 003's SCP on a multi-interval CGL mesh (angle of attack and bank as states, their rates
as controls, free final time) as hooks of the shared driver (``scp.loop``).

Stage 1 (paper 003 sec. 4): a constant-control reference, propagated from the initial state down
to the terminal altitude. Each iteration then solves the convex subproblem about the reference
(``subproblem.build``: collocation rows relaxed by an L1 virtual control, linearized path limits
and zones with L1 slacks, a quadratic penalty on the step) and judges the step by the ratio of
the actual to the predicted decrease of the exactly penalized cost (objective + virtual weight x
the nonlinear defects and violations), the trust-region logic of SCvx (Mao, Szmuk & Acikmese
2016) with a quadratic penalty in place of a hard radius: a poor ratio rejects the step and
doubles the weight, a good one halves it. A step is small when no point moved beyond the stop
tolerances, the final time settled and the nonlinear defects are within the defect tolerance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Unpack

import numpy as np
from scipy.integrate import solve_ivp

from app.schemas.methods.hp_scp import HpScpOptions
from worker.solver.conic import ConeProblem, ConicSolution
from worker.solver.methods.base import FINAL_EXTREMES, MethodResult, RunHooks, run_method
from worker.solver.methods.hp_scp.linearization import (
    PHI,
    THETA,
    HpIterate,
    Linearization,
    V,
    curvature_blocks,
    finite,
    gathered_multipliers,
    linearize,
)
from worker.solver.methods.hp_scp.mesh_update import assess, refined
from worker.solver.methods.hp_scp.stop import SettledProbe
from worker.solver.methods.hp_scp.subproblem import (
    Columns,
    ObjectiveWeights,
    Units,
    build,
    effort_integral,
    model_curvature,
    slacked_multipliers,
    step_of,
)
from worker.solver.models.alpha_bank_state import ALPHA, SIGMA, alpha_bank_state_dynamics
from worker.solver.models.layout import ALPHA_BANK_STATE
from worker.solver.objective_weights import term_pulls
from worker.solver.problem import EntryProblem
from worker.solver.scp import loop as scp
from worker.solver.scp.filter import NonMonotoneFilter
from worker.solver.scp.history import IterationRecord, solver_fields
from worker.solver.scp.penalty import VariableQuadraticPenalty
from worker.solver.scp.ratio import RatioThresholds, TrustRegion, Verdict, step_ratio
from worker.solver.trajectory import OptimizedTrajectory
from worker.solver.transcription.cgl import ChebyshevMesh
from worker.solver.transcription.cgl_collocation import CollocationPattern, PolynomialAttitude
from worker.solver.transcription.terminal import TerminalRow, terminal_rows

Array = np.ndarray
EFFORT_UNIT_DEG = 0.5
"""Trust unit of the control effort (deg of attitude motion), as of the final latitude."""
GUESS_BANK_SHARE = 0.375
"""Default guess bank: this share of the bank range's half-width above its middle."""
FINAL_TIME_UNIT_S = 10.0
"""Unit of the scaled final-time change (s)."""
RATE_UNIT_DEG_S = 1.0
"""Unit of the scaled bank- and alpha-rate changes (deg/s)."""
RATIO = RatioThresholds(reject=0.1, shrink=0.1, grow=0.75)
"""Ratio test (SCvx): below ``reject`` the step is rejected, above ``grow`` the trust weight is
halved; in between it is kept."""
RATIO_EXACT, LIGHTEN_EXACT = 0.1, 0.25
"""A ratio within RATIO_EXACT of 1 (the model predicted the decrease) divides the trust weight
by 1 / LIGHTEN_EXACT (4) instead of 2."""
PREDICTED_FLOOR = 1.0e-12
"""A predicted decrease at most this share of the penalized cost gives ratio 1 (nothing to
judge the step by)."""
STALL_RELATIVE = 1.0e-6
"""A predicted decrease below this share of the penalized cost, with the step rejected, means
the reference is stationary on its mesh."""
REFINED_TRUST_WEIGHT = 1.0e-3
"""Lightest trust weight of the first step on a refined mesh."""
PROBE_FACTOR = 16.0
"""Factor that lightens the trust weight after a small step taken at a weight above its floor."""
TRUST_WEIGHT_MAX = 1.0e8
"""Heaviest trust weight before the method gives up on a step (the reference is stationary for
the penalized cost within the solver's precision)."""


PAPER_TRUST_BOX = {
    "altitude_m": 20_000.0,
    "velocity_m_s": 500.0,
    "longitude_deg": 20.0,
    "latitude_deg": 20.0,
    "flight_path_angle_deg": 20.0,
    "heading_deg": 70.0,
    "bank_deg": 70.0,
    "angle_of_attack_deg": 20.0,
}
"""Paper 003 sec. 5's hard trust region delta per state (its order: h, V, lon, lat, gamma, psi,
sigma, alpha)."""
BOX_RATE_DEG_S = 10.0
"""Hard trust region of the bank and alpha rates (deg/s; the paper bounds only the states)."""
BOX_FINAL_TIME_S = 100.0
"""Hard trust region of the final time (s)."""


FILTER_VIOLATION_FACTOR = 10.0
"""The filter's largest admissible violation: this many times the guess's (at least 1)."""
KKT_RELATIVE = 1.0e-2
"""A converged penalized step: w |d| (the true problem's KKT residual) within this share of
the objective's gradient."""
LINE_SEARCH_MIN = 1.0 / 16.0
"""Shortest step fraction the line search tries."""
VIRTUAL_WEIGHT_FLOOR = 1.0
"""Lightest virtual-control weight the multipliers may steer to (per trust unit)."""
HOLD_RELEASE = 1.0e-4
"""Largest virtual control (scaled) at which the held final time is freed."""


@dataclass
class _Pending:
    """What judging a proposal needs: the candidate's linearization, the predicted cost, the
    step's size test."""

    linearization: Linearization
    predicted: float
    small_step: bool
    virtual: float


@dataclass
class HpState:
    """The ratio test's state: the trust weight and the reference's penalized cost."""

    trust: TrustRegion
    cost: float | None = None


class HpScp:
    """Paper 003's method on the driver: start, linearize, build, propose, judge."""

    def __init__(self, problem: EntryProblem, options: HpScpOptions) -> None:
        self.problem, self.options = problem, options
        sc = problem.scales
        self.mesh = ChebyshevMesh.uniform(options.intervals, options.degree)
        self.pattern = CollocationPattern.of(self.mesh, 8, 2)
        rate_unit = math.radians(RATE_UNIT_DEG_S) * sc.time_s
        self.units = Units(
            ALPHA_BANK_STATE.trust_units(sc), np.full(2, rate_unit), FINAL_TIME_UNIT_S / sc.time_s
        )
        self.terminal: list[TerminalRow] = terminal_rows(
            problem,
            ALPHA_BANK_STATE,
            fixed="virtual",
            virtual_weight=options.weight_virtual_control,
            trust_units=self.units.z,
        )
        self.tol_z = ALPHA_BANK_STATE.deltas_from_si(options.stop_tolerance, sc)
        self.tol_t = options.stop_tolerance.final_time_s / sc.time_s
        self.state = HpState(
            TrustRegion(
                options.weight_trust_region,
                options.weight_trust_region_min,
                TRUST_WEIGHT_MAX,
                penalty=True,
            )
        )
        self.w_vc = options.weight_virtual_control
        self.accepted_costs: list[float] = []
        self.probe = SettledProbe()
        self.penalty = VariableQuadraticPenalty(
            initial_weight=options.weight_trust_region,
            rule=options.penalty_rule,
            minimum=options.weight_trust_region_min,
        )
        self.filter = NonMonotoneFilter()
        self.holding = options.final_time_guess_s is not None and options.hold_final_time
        self.box = (
            ALPHA_BANK_STATE.deltas_from_si(PAPER_TRUST_BOX, sc)
            if options.trust_box or options.globalization == "paper"
            else None
        )
        self.box_rates = math.radians(BOX_RATE_DEG_S) * sc.time_s
        self.box_tf = BOX_FINAL_TIME_S / sc.time_s
        self.extra: dict[str, Any] = {}
        self.pending: _Pending | None = None
        self.steered: float | None = None
        """The virtual-control weight the last subproblem's multipliers call for (None: the
        schedule's)."""
        self.between_on = options.between_points == "always"
        """Whether the attitude's bounds hold between the points and the path limits are
        sampled there (``subproblem._between_points``)."""
        self.cols: Columns | None = None
        self.objective: ObjectiveWeights | None = None

    # -- stage 1: the constant-control reference ------------------------------------------
    def start(self) -> HpIterate:
        """Constant bank and angle of attack flown from the initial state to the terminal
        altitude (or the guessed flight time), sampled at the mesh points."""
        p, o = self.problem, self.options
        if p.guess is not None:
            return self._start_from_guess()
        if p.initial_bank is not None:
            bank = p.initial_bank
        elif o.initial_bank_deg is not None:
            bank = math.radians(o.initial_bank_deg)
        else:
            bank = 0.5 * (p.bank_min + p.bank_max) + GUESS_BANK_SHARE * 0.5 * (
                p.bank_max - p.bank_min
            )
        bank = min(max(bank, p.bank_min), p.bank_max)
        alpha = (
            p.initial_alpha if p.initial_alpha is not None else math.radians(o.initial_alpha_deg)
        )
        if p.alpha_range is not None:
            alpha = min(max(alpha, p.alpha_range[0]), p.alpha_range[1])
        z0 = np.concatenate([p.y0, [bank, alpha]])
        w0 = np.zeros((1, 2))

        def rhs(t: float, z: Array) -> Array:
            dyn = alpha_bank_state_dynamics(z[None, :], w0, p.forces, p.omega, jacobians=False)
            return dyn.F[0]

        events = []
        target = p.terminal["altitude_m"].target()
        lat_t, lon_t = p.terminal["latitude_deg"].target(), p.terminal["longitude_deg"].target()
        if lat_t is not None and lon_t is not None and o.final_time_guess_s is None:
            # the closest approach to the target point

            def approach(t: float, z: Array) -> float:
                # d/dt of cos(central angle to the target): 0 at the closest approach
                f = rhs(t, z)
                dc_dphi = math.cos(z[PHI]) * math.sin(lat_t) - math.sin(z[PHI]) * math.cos(
                    lat_t
                ) * math.cos(z[THETA] - lon_t)
                dc_dth = -math.cos(z[PHI]) * math.cos(lat_t) * math.sin(z[THETA] - lon_t)
                return float(dc_dphi * f[PHI] + dc_dth * f[THETA])

            approach.terminal = True  # type: ignore[attr-defined]
            approach.direction = -1.0  # type: ignore[attr-defined]
            events.append(approach)
        if target is not None:

            def down(t: float, z: Array) -> float:
                return float(z[0] - target)

            down.terminal = True  # type: ignore[attr-defined]
            events.append(down)
        t_span = (
            o.final_time_guess_s / p.scales.time_s
            if o.final_time_guess_s is not None
            else 20.0 * math.sqrt(2.0)  # a ceiling: the altitude event ends it first
        )
        sol = solve_ivp(
            rhs, (0.0, t_span), z0, rtol=1e-8, atol=1e-10, events=events, dense_output=True
        )
        if sol.status == -1 or sol.t[-1] <= 0.0:
            raise scp.StartError(
                "initial_guess",
                f"the constant-control guess (bank {math.degrees(bank):.1f} deg, alpha "
                f"{math.degrees(alpha):.1f} deg) could not be propagated: {sol.message}",
            )
        tf = float(sol.t[-1]) if o.final_time_guess_s is None else t_span
        tf = min(tf, float(sol.t[-1]))
        t = self.mesh.points(0.0, tf)
        z = sol.sol(t).T
        if o.guess == "linear":  # straight from the initial to the terminal targets
            tau = t / tf
            for j, key in ALPHA_BANK_STATE.terminal_states():
                end = p.terminal[key].target()
                if end is not None:
                    z[:, j] = (1.0 - tau) * z0[j] + tau * end
            z[:, SIGMA], z[:, ALPHA] = bank, alpha
        self.extra["initial_guess"] = {
            "bank_deg": math.degrees(bank),
            "alpha_deg": math.degrees(alpha),
            "final_time_s": tf * p.scales.time_s,
        }
        self.tf_guess = tf
        self.objective = self._objective()
        return HpIterate(z, np.zeros((z.shape[0], 2)), tf, self.pattern)

    def _start_from_guess(self) -> HpIterate:
        """The caller's trajectory on the mesh over its own flight time (the final time is
        free): states and bank interpolated, the angle of attack from the guess (else the
        method's initial value), each within its bounds, the initial state at the first point."""
        p, o = self.problem, self.options
        assert p.guess is not None
        tf = float(p.guess.t[-1])
        t = self.mesh.points(0.0, tf)
        y, bank = p.guess.on_times(t)
        y[0] = p.y0
        alpha = p.guess.alpha_on_times(t)
        if alpha is None:
            start = p.initial_alpha if p.initial_alpha is not None else o.initial_alpha_deg
            alpha = np.full(t.size, start if p.initial_alpha is not None else math.radians(start))
        if p.initial_bank is not None:
            bank[0] = p.initial_bank
        if p.initial_alpha is not None:
            alpha[0] = p.initial_alpha
        bank = np.clip(bank, p.bank_min, p.bank_max)
        if p.alpha_range is not None:
            alpha = np.clip(alpha, *p.alpha_range)
        z = np.column_stack([y, bank, alpha])
        self.extra["initial_guess"] = {"final_time_s": tf * p.scales.time_s}
        self.tf_guess = tf
        self.objective = self._objective()
        return HpIterate(z, np.zeros((z.shape[0], 2)), tf, self.pattern)

    def _objective(self) -> ObjectiveWeights:
        """Weights of the objective terms, scaled so that the objective pulls the steps as
        strongly as the trust penalty holds them: a single term per trust unit of what it
        measures (the final time's 10 s, the final latitude's or longitude's 0.5 deg, the
        speed's 50 m/s, the control effort's 0.5 deg); several terms keep the caller's
        weights between them in SI units (s, m/s, deg; ``objective_weights.term_pulls``). Max terms
        negated."""
        p = self.problem
        u, sc = self.units, self.problem.scales
        per_unit = {  # each term's trust unit in SI (the unit of its value)
            "min_time": u.t * sc.time_s,
            "max_terminal_velocity": u.z[V] * sc.speed_m_s,
            "min_control_effort": EFFORT_UNIT_DEG,
        }
        for name in FINAL_EXTREMES:
            index = PHI if name.endswith("latitude") else THETA
            per_unit[name] = math.degrees(u.z[index])
        terms = list(p.objective)
        pulls = term_pulls([t.weight for t in terms], [per_unit[t.name] for t in terms])
        final = np.zeros(8)
        tf = effort = 0.0
        for term, pull in zip(terms, pulls, strict=True):
            if term.name == "min_time":
                tf += pull / u.t
            elif term.name == "max_terminal_velocity":
                final[V] -= pull / u.z[V]
            elif term.name == "min_control_effort":
                effort += pull / math.radians(EFFORT_UNIT_DEG)
            elif term.name.endswith("final_latitude") or term.name.endswith("final_longitude"):
                sign = -1.0 if term.name.startswith("max") else 1.0
                index = PHI if term.name.endswith("latitude") else THETA
                final[index] += sign * pull / u.z[index]
        return ObjectiveWeights(tf, final, effort)

    # -- the driver's hooks --------------------------------------------------------------
    def linearize(self, reference: HpIterate) -> Linearization:
        """Dynamics, defects, path and zone rows about ``reference``."""
        return linearize(self.problem, reference)

    def subproblem(
        self, reference: HpIterate, linearization: Linearization, iteration: int
    ) -> ConeProblem:
        """The subproblem with the current trust weight."""
        assert self.objective is not None
        o = self.options
        self.w_vc = min(
            o.weight_virtual_control_initial * o.virtual_control_growth ** (iteration - 1),
            o.weight_virtual_control,
        )
        if self.steered is not None:
            self.w_vc = min(self.w_vc, self.steered)
        problem, self.cols = self._build(reference, linearization, hold_time=self.holding)
        self.q, self.P = problem.q, problem.P
        self.reference_linearization = linearization
        self.state.cost = self.penalized(reference, linearization)  # at this iteration's weight
        return problem

    def objective_gradient(self) -> Array:
        """The objective's gradient in the scaled step variables (its linear part)."""
        assert self.objective is not None and self.cols is not None
        g = np.zeros(self.cols.steps)
        g[self.cols.t] = self.objective.tf * self.units.t
        g[self.cols.z(self.cols.K - 1, np.arange(8))] = self.objective.final * self.units.z
        return g

    def _settled(self) -> bool:
        """Whether the objective moved by less than ``stop_tolerance.relative_cost`` over the
        last ``stop_tolerance.settle_iterations`` accepted steps (a slow drift along a valley of
        the chattering attitude arcs ends the run once it no longer moves the objective)."""
        tol = self.options.stop_tolerance
        n = tol.settle_iterations
        if len(self.accepted_costs) <= n:
            return False
        old, new = self.accepted_costs[-n - 1], self.accepted_costs[-1]
        return abs(old - new) <= tol.relative_cost * max(abs(new), 1.0)

    def _build(
        self,
        reference: HpIterate,
        linearization: Linearization,
        *,
        hold_time: bool,
        restoring: bool = False,
    ) -> tuple[ConeProblem, Columns]:
        """The subproblem about ``reference`` with this iteration's weights and regions;
        ``restoring``: without the objective (a correction's step back onto the constraints)."""
        assert self.objective is not None
        objective = self.objective
        if restoring:
            objective = ObjectiveWeights(0.0, np.zeros_like(objective.final))
        return build(
            self.problem,
            reference,
            linearization,
            self.units,
            self.terminal,
            objective,
            weight_virtual=self.w_vc,
            weight_trust=self._trust_weight(),
            tf_min=0.05 * self.tf_guess,
            box=self.box if self._boxed() else None,
            box_rates=self.box_rates,
            box_tf=self.box_tf,
            hold_time=hold_time,
            rate_weight=self.options.weight_rate_regularization,
            curvature=self._curvature(reference),
            between_points=self.between_on,
        )

    def _curvature(self, reference: HpIterate) -> Array | None:
        """The Lagrangian curvature about ``reference`` from the multipliers of the subproblem
        that made it (None before the first, or when ``second_order`` is off)."""
        mu = reference.multipliers
        if not self.options.second_order or mu is None:
            return None
        units = np.concatenate([self.units.z, self.units.w])
        return curvature_blocks(self.problem, reference, mu, units)

    def _trust_weight(self) -> float:
        """The step's quadratic weight: the ratio test's, or paper 003's stage (none under the
        hard trust region, then the variable penalty)."""
        if self.options.globalization == "paper":
            return 0.0 if self.penalty.hard else self.penalty.weight
        return self.state.trust.size

    def _boxed(self) -> bool:
        """Whether the hard trust region is in the subproblem."""
        if self.options.globalization == "paper":
            return self.penalty.hard
        return self.box is not None

    def solve(
        self, problem: ConeProblem, conic: scp.ConicCall, limit_s: float, deadline: float
    ) -> ConicSolution:
        """One solve (the conic call is kept for the step's second-order corrections)."""
        self._conic, self._limit = conic, limit_s
        return conic(problem, limit_s)

    def _corrected(
        self, reference: HpIterate, new: HpIterate, candidate: Linearization
    ) -> tuple[HpIterate, Linearization, int]:
        """Second-order corrections of a step (Nocedal & Wright, Numerical Optimization, sec.
        18.3; against the Maratos effect of the exact L1 penalty, which would reject the
        tangential steps whose defects are second order): the shortest step (the trust
        penalty's) onto the constraints linearized about the candidate, with the final time
        held and without the objective's pull, kept while the penalized cost falls."""
        assert self.objective is not None
        passes = 0
        for _ in range(self.options.second_order_corrections):
            if not finite(candidate):
                break
            if self._defect(candidate) <= self.options.defect_tolerance:
                break
            problem, cols = self._build(new, candidate, hold_time=True, restoring=True)
            solution = self._conic(problem, self._limit)
            self.correction_s += solution.solve_time_s
            if not solution.status.usable or solution.x is None:
                break
            dz, dw, _ = step_of(solution.x, cols, self.units)
            trial = HpIterate(new.z + dz, new.w + dw, new.tf, new.pattern, new.multipliers)
            lin = linearize(self.problem, trial)
            if not finite(lin) or self.penalized(trial, lin) >= self.penalized(new, candidate):
                break
            new, candidate = trial, lin
            passes += 1
        return new, candidate, passes

    def _defect(self, lin: Linearization) -> float:
        """The largest nonlinear collocation defect of ``lin`` (trust units)."""
        return float(np.max(np.abs(lin.defects) / self.units.z[None, :]))

    def violation(self, ref: HpIterate, lin: Linearization) -> float:
        """The constraint violation of paper 003's filter: scaled L1 of the collocation defects,
        path and zone excesses (log units, rad) and fixed terminal misses (trust units)."""
        u = self.units.z
        c = float(np.sum(np.abs(lin.defects) / u[None, :]))
        excess = lin.path_excess() if self.between_on else np.maximum(lin.path.g, 0.0)
        c += float(np.sum(excess))
        c += float(np.sum(np.maximum(-lin.zone_c, 0.0)))
        for row in self.terminal:
            if row.kind == "soft" and row.virtual:
                c += abs(ref.z[-1, row.state] - row.value) / u[row.state]
        return c

    def _linear_objective(self, ref: HpIterate) -> float:
        """The objective terms on ``ref`` (per trust unit): linear in the final time and the
        last point, and the control effort's product t_f S exactly."""
        assert self.objective is not None
        f = self.objective.tf * ref.tf + float(self.objective.final @ ref.z[-1])
        if self.objective.effort:
            f += self.objective.effort * effort_integral(ref)
        return f

    def _effort_anchor(self, ref: HpIterate) -> float:
        """What the subproblem's effort columns cost at the reference (their absolute values
        are in q x; subtracted to make q x a change)."""
        assert self.objective is not None
        return self.objective.effort * effort_integral(ref) if self.objective.effort else 0.0

    def objective_value(self, ref: HpIterate) -> float:
        """The linear objective (per trust unit) plus the rate regularization."""
        f = self._linear_objective(ref)
        reg = self.options.weight_rate_regularization
        if reg > 0.0:
            f += reg * float(np.mean(np.sum((ref.w / self.units.w[None, :]) ** 2, axis=1)))
        return f

    def _line_search(
        self, reference: HpIterate, proposal: scp.Proposal[HpIterate], pending: _Pending
    ) -> scp.Judgement[HpIterate, Linearization]:
        """Paper 003 step 2.2: backtrack beta = 1, 1/2, ... along the step until the
        non-monotone filter accepts (c, f) of reference + beta d; the penalty stage and weight
        follow the accepted step (eqs. 61, 77-79). No acceptable beta: rejected, weight x10."""
        record = proposal.record
        new = proposal.reference
        if not self.filter.history:
            lin0 = linearize(self.problem, reference, jacobians=False)
            c0 = self.violation(reference, lin0)
            self.filter.c_max = FILTER_VIOLATION_FACTOR * max(c0, 1.0)
            self.filter.start(c0, self.objective_value(reference))
        beta = 1.0
        trials = 0
        while beta >= LINE_SEARCH_MIN:
            trials += 1
            trial = (
                new
                if beta == 1.0
                else HpIterate(
                    reference.z + beta * (new.z - reference.z),
                    reference.w + beta * (new.w - reference.w),
                    reference.tf + beta * (new.tf - reference.tf),
                    reference.pattern,
                )
            )
            lin = pending.linearization if beta == 1.0 else linearize(self.problem, trial)
            if finite(lin):
                c, f = self.violation(trial, lin), self.objective_value(trial)
                if self.filter.acceptable(c, f):
                    self.filter.accept(c, f)
                    break
            beta *= 0.5
        record.extra["line_search"] = {"beta": beta, "trials": trials}
        if beta < LINE_SEARCH_MIN:
            self.penalty.infeasible()
            if self.penalty.hard:
                self.penalty.stage = "penalty"
            record.extra["rejected"] = "no step length the filter accepts"
            return scp.Judgement(accepted=False, linearization=None)
        assert self.cols is not None
        step = beta * np.concatenate(
            [
                ((new.z - reference.z) / self.units.z).ravel(),
                ((new.w - reference.w) / self.units.w).ravel(),
            ]
        )
        gradient = float(np.linalg.norm(self.objective_gradient()))
        weight = self._trust_weight()
        # the true problem's KKT residual at a penalized step is w d (paper 003 Theorem 1)
        kkt = weight * float(np.max(np.abs(step))) if step.size else 0.0
        self.penalty.observe(
            self.objective_value(trial), float(np.linalg.norm(step)), gradient, beta == 1.0
        )
        record.extra.update(self.penalty.describe())
        record.extra["kkt_residual"] = kkt
        change = beta * np.max(np.abs(new.z - reference.z), axis=0)
        small = bool(
            beta == 1.0
            and np.all(change <= self.tol_z)
            and abs(new.tf - reference.tf) <= self.tol_t
            and record.linearization_error <= self.options.defect_tolerance
            and kkt <= KKT_RELATIVE * max(gradient, 1e-12)
        )
        proposal.reference = trial
        pending.linearization = lin
        return self._accept(proposal, pending, small)

    def penalized(self, ref: HpIterate, lin: Linearization) -> float:
        """The cost the steps decrease: the objective (with the rate regularization) plus the
        virtual weight times the filter's violation, plus the soft terminal conditions at their
        own weights."""
        u = self.units.z
        cost = self.objective_value(ref) + self.w_vc * self.violation(ref, lin)
        for row in self.terminal:
            if row.kind == "soft" and not row.virtual:
                cost += row.weight * abs(ref.z[-1, row.state] - row.value) / u[row.state]
        return cost

    def propose(
        self,
        reference: HpIterate,
        linearization: Linearization,
        solution: ConicSolution,
        iteration: int,
    ) -> scp.Proposal[HpIterate]:
        """The candidate, its linearization and the record."""
        assert solution.x is not None and self.cols is not None and self.objective is not None
        x = solution.x
        dz, dw, dtf = step_of(x, self.cols, self.units)
        new = HpIterate(reference.z + dz, reference.w + dw, reference.tf + dtf, reference.pattern)
        if solution.y is not None:  # the collocation rows' multipliers, unscaled
            rows = solution.y[: self.cols.collocation_rows].reshape(-1, 8) / self.units.z[None, :]
            new.multipliers = gathered_multipliers(reference.pattern, rows)
        kappa = self.options.virtual_control_steering
        if kappa > 0.0 and solution.y is not None:
            lam = slacked_multipliers(solution.y, self.cols, self.w_vc)
            self.steered = max(kappa * lam, VIRTUAL_WEIGHT_FLOOR)
        candidate = linearize(self.problem, new)
        self.correction_s = 0.0
        new, candidate, corrections = self._corrected(reference, new, candidate)
        dz = new.z - reference.z
        predicted = self.objective_value(reference) + float(self.q @ x)
        predicted -= self._effort_anchor(reference)
        predicted += model_curvature(self.P, x, self._trust_weight(), self.cols.steps)
        change = np.max(np.abs(dz), axis=0)
        slack = x[self.cols.nu_plus :]
        virtual = float(np.max(slack)) if slack.size else 0.0
        small_step = bool(np.all(change <= self.tol_z) and abs(dtf) <= self.tol_t)
        defect = self._defect(candidate)
        sc = self.problem.scales
        terms = self._term_values(new)
        record = IterationRecord(
            iteration=iteration,
            cost=next(iter(terms.values())) if len(terms) == 1 else predicted,
            cost_terms={**terms, "final_time_s": new.tf * sc.time_s},
            objective_value=None,
            max_state_change=ALPHA_BANK_STATE.deltas_to_si(change, sc),
            trust_region_slack=float(np.sum(x[: self.cols.steps] ** 2)),
            virtual_control_norm=float(np.sum(slack)),
            linearization_error=defect,
            nodes_post_corrected=None,
            relaxation_gap=None,
            subproblem_cost=predicted,
            extra={
                "trust_weight": self.state.trust.size,
                "virtual_weight": self.w_vc,
                "mesh_intervals": reference.pattern.mesh.num_intervals,
                "mesh_points": reference.pattern.mesh.num_points,
                "final_time_change_s": dtf * sc.time_s,
                "corrections": corrections,
            },
            **solver_fields(solution),
        )
        self.pending = _Pending(candidate, predicted, small_step, virtual)
        return scp.Proposal(new, record)

    def judge(
        self, reference: HpIterate, proposal: scp.Proposal[HpIterate]
    ) -> scp.Judgement[HpIterate, Linearization]:
        """SCvx's ratio test on the penalized cost, with the quadratic penalty's weight as the
        trust region."""
        pending, record, state = self.pending, proposal.record, self.state
        assert pending is not None and state.cost is not None
        self.pending = None
        record.extra["final_time_held"] = self.holding
        if self.options.globalization == "paper":
            return self._line_search(reference, proposal, pending)
        if not finite(pending.linearization):
            state.trust.shorten(4.0)
            record.extra["rejected"] = "the step left the models' range"
            return scp.Judgement(accepted=False, linearization=None)
        candidate = self.penalized(proposal.reference, pending.linearization)
        step = step_ratio(state.cost, candidate, pending.predicted, PREDICTED_FLOOR)
        ratio, predicted, verdict = step.value, step.predicted, RATIO.verdict(step.value)
        record.extra.update(step.describe())
        defect_ok = record.linearization_error <= self.options.defect_tolerance
        if self.options.acceptance == "always":
            return self._accept(proposal, pending, pending.small_step and defect_ok)
        if (
            verdict is Verdict.REJECT
            and predicted <= STALL_RELATIVE * max(1.0, abs(state.cost))
            and self._defect(self.reference_linearization) <= self.options.defect_tolerance
        ):
            # the model sees no progress worth a step and the step it offers fails: the
            # reference is stationary on this mesh (kept, and judged as converged)
            record.extra["rejected"] = f"stationary: predicted decrease {predicted:.3g}"
            proposal.reference = reference
            pending.linearization = self.reference_linearization
            return self._accept(proposal, pending, True)
        if verdict is Verdict.REJECT and not (pending.small_step and defect_ok):
            state.trust.shorten()
            record.extra["rejected"] = f"ratio {ratio:.3g} below {RATIO.reject}"
            return scp.Judgement(accepted=False, linearization=None)
        if verdict is Verdict.GROW:
            # a model that predicted the decrease within RATIO_EXACT is lightened faster
            state.trust.lengthen(2.0 if abs(ratio - 1.0) > RATIO_EXACT else 1.0 / LIGHTEN_EXACT)
        self.accepted_costs.append(self.objective_value(proposal.reference))
        small, probe = self.probe.judge(
            pending.small_step,
            self._settled(),
            defect_ok,
            can_lighten=not self.holding and not state.trust.at_longest,
        )
        if probe:
            # small only because the trust weight holds it: lighten the weight and go on, so
            # that a converged step is one the trust penalty no longer shapes
            state.trust.lengthen(PROBE_FACTOR)
        if self.holding and (pending.virtual <= HOLD_RELEASE or small):
            self.holding, small = False, False  # feasible at the guessed time: free it
        return self._accept(proposal, pending, small)

    def _accept(
        self, proposal: scp.Proposal[HpIterate], pending: _Pending, small: bool
    ) -> scp.Judgement[HpIterate, Linearization]:
        """Accept the proposal; when it has converged on its mesh, assess the mesh and move the
        reference onto the refined mesh when an interval fails (then the run goes on)."""
        record = proposal.record
        if small and not self.between_on:
            # "staged": converged with the attitude bounded at the points only; now on the
            # whole polynomials (the step is kept, its linearization redone with the new rows)
            self.between_on = True
            record.extra["between_points"] = "on"
            self.accepted_costs.clear()
            self.probe.reset()
            self.state.trust.at_most_as_long_as(REFINED_TRUST_WEIGHT)
            return scp.Judgement(accepted=True, small=False, virtual_control=pending.virtual)
        if self.options.mesh == "adaptive" and small:
            assessment = assess(self.problem, proposal.reference, self.units.z, self.options)
            record.extra["mesh_assessment"] = assessment.summary()
            new = refined(proposal.reference, assessment, self.options.max_mesh_points)
            if new is not None:
                mesh = new.pattern.mesh
                # the new points' defects make the first steps on a new mesh long ones: a
                # weight left at its floor is rejected many times before it recovers
                self.state.trust.at_most_as_long_as(REFINED_TRUST_WEIGHT)
                self.accepted_costs.clear()  # the settling test starts again on the new mesh
                self.probe.reset()
                record.extra["mesh_refined"] = {
                    "intervals": mesh.num_intervals,
                    "points": mesh.num_points,
                }
                return scp.Judgement(
                    accepted=True, small=False, virtual_control=pending.virtual, reference=new
                )
        return scp.Judgement(
            accepted=True,
            small=small,
            virtual_control=pending.virtual,
            linearization=pending.linearization,
        )

    def trajectory(self, reference: HpIterate) -> OptimizedTrajectory:
        """The points as a time trajectory, bank and alpha as the mesh's polynomials."""
        t = reference.pattern.mesh.points(0.0, reference.tf)
        z = reference.z
        attitude = PolynomialAttitude(
            reference.pattern.mesh, reference.tf, z[:, SIGMA], z[:, ALPHA]
        )
        return OptimizedTrajectory(
            "time",
            t,
            z[:, :6].copy(),
            t,
            z[:, SIGMA].copy(),
            alpha_deg=np.degrees(z[:, ALPHA]),
            attitude=attitude,
        )

    def objective_terms(self, outcome: scp.ScpOutcome[HpIterate]) -> dict[str, float]:
        """Each term's value (SI) on the last reference."""
        return {} if outcome.reference is None else self._term_values(outcome.reference)

    def _term_values(self, ref: HpIterate) -> dict[str, float]:
        """Each objective term's value (SI: s, m/s, deg) on ``ref``."""
        sc = self.problem.scales
        values: dict[str, float] = {}
        for term in self.problem.objective:
            if term.name == "min_time":
                values[term.name] = ref.tf * sc.time_s
            elif term.name == "max_terminal_velocity":
                values[term.name] = float(ref.z[-1, V]) * sc.speed_m_s
            elif term.name.endswith("final_latitude"):
                values[term.name] = math.degrees(float(ref.z[-1, PHI]))
            elif term.name.endswith("final_longitude"):
                values[term.name] = math.degrees(float(ref.z[-1, THETA]))
            elif term.name == "min_control_effort":
                values[term.name] = math.degrees(effort_integral(ref))
        return values


def run(problem: EntryProblem, options: HpScpOptions, **hooks: Unpack[RunHooks]) -> MethodResult:
    """Run paper 003's SCP on ``problem`` with its ``options``."""
    return run_method(lambda: HpScp(problem, options), options, hooks)
