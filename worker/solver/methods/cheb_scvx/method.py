"""Paper 001's Chebyshev pseudospectral SCvx as hooks of the shared driver (``scp.loop``).

Each iteration linearizes the dynamics with the lift vector as control about the reference at
the CGL points (eqs. 26-31), adds the path rows at the points where the reference violates (or
nears) a limit (sec. 3.2.2, step 2; a point once added stays), solves problem P2 (eqs. 35-42)
relaxed by L1 virtual control, and judges the step by SCvx's ratio of the actual to the
predicted decrease of the penalized cost (Mao, Szmuk & Acikmese 2016): a poor ratio rejects it
and halves the trust box, a good one doubles it (the paper's fixed box of eq. 44 is the
initial one). Converged when an accepted step moves no point beyond the stop tolerances (eq. 43)
with the defects, slacks and virtual control spent.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass
from typing import Any, Unpack

import numpy as np

from app.schemas.methods.cheb_scvx import ChebScvxOptions
from worker.solver.conic import ConeProblem, ConicSolution, ConicStatus
from worker.solver.constraints.log_path import active_limits
from worker.solver.methods.base import MethodResult, RunHooks, run_method
from worker.solver.methods.cheb_scvx.lift_share import alpha_of_share, share_problem
from worker.solver.methods.cheb_scvx.linearization import (
    ChebIterate,
    ChebLinearization,
    linearize,
)
from worker.solver.methods.cheb_scvx.segments import LiftVectorPath, Segments
from worker.solver.methods.cheb_scvx.start import (
    OBJECTIVE_STEERING_GAIN,
    guess_start,
    guided_start,
    leg_length,
    objective_point,
    propagated_start,
    route_points,
    route_start,
)
from worker.solver.methods.cheb_scvx.subproblem import (
    BOUND_UNIT,
    GAP_UNIT,
    PATH_UNIT,
    ZONE_UNIT,
    Columns,
    Setup,
    TerminalBound,
    Units,
    Waypoint,
    build,
    smoothing,
    step_of,
)
from worker.solver.models.layout import POINT_MASS
from worker.solver.models.lift_vector import PlanetModel, lift_law
from worker.solver.models.point_mass import PH, TH, V
from worker.solver.objective_weights import term_pulls
from worker.solver.problem import EntryProblem
from worker.solver.scp import loop as scp
from worker.solver.scp.history import IterationRecord, solver_fields
from worker.solver.scp.ratio import RatioThresholds, TrustRegion, Verdict, step_ratio
from worker.solver.trajectory import OptimizedTrajectory
from worker.solver.verification import verify

Array = np.ndarray
LIFT_UNIT = 0.1
"""Unit of the scaled lift-vector changes."""
FINAL_TIME_UNIT_S = 10.0
"""Unit of the scaled segment-duration changes (s)."""
HEAT_LOAD_UNIT = 1.0e6
"""Unit of the heat-load objective term (J/m^2)."""
RATIO = RatioThresholds(reject=0.0, shrink=0.25, grow=0.7)
"""SCvx's ratio thresholds: reject below the first, shrink the box below the second, grow it
above the third (Mao, Szmuk & Acikmese 2016, Algorithm 1)."""
RADIUS_MAX, RADIUS_MIN = 4.0, 1.0e-6
"""Largest and smallest trust-box scale against the initial box."""
GAP_SWITCH = 1.0e-3
"""A converged answer whose relaxed cone is slacker than this somewhere (u3 - u1^2 - u2^2) goes
on with the lift vector on its manifold (``Setup.on_manifold``)."""
DRIFT_SWITCH = 0.2
"""... and whose unflown lift would move the flight by more than this (trust units:
``ChebScvx.unflown_drift``): a slack cone where the air is too thin to matter flies as planned."""
RELAXED_SMOOTHING = 0.1
"""Off the manifold, the tie-breaking smoothing's share of ``weight_lift_smoothing``: at the
full weight it would rather leave lift unused (a flight the vehicle cannot fly) than turn it."""
FEASIBLE = 1.0e-3
"""Largest defect or slack (scaled units: 1 km, 0.5 deg, 50 m/s ..., 1 % of a limit) of a
reference that may be called converged."""
RETRY_REGULARIZATION = 10.0
"""Factor of the step regularization when a subproblem is solved again after a numerical stall."""
WAYPOINT_MARGIN = 0.95
"""Share of a waypoint's radius the points must pass within: the flight between the points and
the tangent-plane metric on the sphere get the rest."""
STATIONARY = 1.0e-9
"""A predicted decrease below this share of the penalized cost: nothing left to gain."""
MERIT_MARGIN = 3.0
"""The merit's penalty weight against the subproblem's largest multiplier of a relaxed row: an
exact L1 penalty needs a weight above the multipliers (Nocedal & Wright, Numerical
Optimization, thm. 17.3); the margin keeps it exact between iterations."""
MERIT_FLOOR = 1.0e-3
"""The merit's smallest penalty weight, as a share of the subproblem's weight."""
PHASE_WINDOW, PHASE_PROGRESS = 20, 0.9
"""A tie-breaking phase whose infeasibility, over its last ``PHASE_WINDOW`` accepted steps, fell
to no less than ``PHASE_PROGRESS`` of itself makes no progress: it ends on the converged answer
it started from, whose flight the result then reports."""
STALL_ITERATIONS, STALL_SHARE = 10, 1.0e-4
"""An infeasibility above ``FEASIBLE`` whose sum stayed within this share of itself over this
many accepted steps has stalled: the run ends infeasible instead of spending its budget."""


@dataclass(frozen=True)
class _Converged:
    """The converged answer a tie-breaking phase starts from (``_breaks_ties``): its reference,
    linearization, largest virtual control and record."""

    reference: ChebIterate
    lin: ChebLinearization
    virtual: float
    record: IterationRecord


@dataclass
class _Pending:
    """The candidate's linearization and penalized cost, the predicted cost, the step's size."""

    lin: ChebLinearization
    cost: float
    predicted: float
    small: bool
    virtual: float


class ChebScvx:
    """Paper 001's method on the driver: start, linearize, build, propose, judge."""

    def __init__(
        self,
        problem: EntryProblem,
        options: ChebScvxOptions,
        model: PlanetModel,
        verified: EntryProblem | None = None,
    ) -> None:
        self.problem, self.options, self.model = problem, options, model
        self.verified = problem if verified is None else verified
        """The problem as the result's verification flies it (``flies``)."""
        self.lift_range = lift_range(problem)
        self.law = lift_law(problem.forces)
        sc = problem.scales
        route = route_points(problem)
        self.route = route
        if route is not None and problem.guess is None:
            lengths = [leg_length(a, b, model) for a, b in itertools.pairwise(route)]
        else:
            lengths = [1.0]
        self.segments = Segments.sized(
            options.nodes, options.intervals, lengths, options.samples_between_points
        )
        self.units = Units(
            POINT_MASS.trust_units(sc), np.full(3, LIFT_UNIT), FINAL_TIME_UNIT_S / sc.time_s
        )
        self.setup = self._setup()
        tr = options.trust_region
        self.box = np.concatenate(
            [
                POINT_MASS.deltas_from_si(tr, sc) / self.units.y,
                np.full(3, tr.lift_control / LIFT_UNIT),
                [tr.final_time_s / sc.time_s / self.units.t],
            ]
        )
        self.trust = TrustRegion(1.0, RADIUS_MIN, RADIUS_MAX)
        """The trust box's scale (a radius against ``box``)."""
        self.tol = POINT_MASS.deltas_from_si(options.stop_tolerance, sc)
        self.tol_t = options.stop_tolerance.final_time_s / sc.time_s
        limits = len(active_limits(problem))
        self.path_set = np.zeros((self.segments.control_points, limits), dtype=bool)
        self.rate_set = np.zeros(self.segments.rate_rows, dtype=bool)
        self.cols: Columns | None = None
        self.q: Array | None = None
        self.pending: _Pending | None = None
        self.ref_cost: float | None = None
        self.merit_weight = options.weight_virtual_control
        """The L1 penalty weight of the ratio test's merit (``merit_weight_of``)."""
        self.objective_bound: float | None = None
        """In the tie-breaking phase: the converged objective, which the answer keeps."""
        self.converged: _Converged | None = None
        """In the tie-breaking phase: the converged answer it started from."""
        self.phase_trail: list[float] = []
        """In the tie-breaking phase: the infeasibility of each accepted step."""
        self.infeasibility_trail: list[float] = []
        """The sum of the scaled violations of each accepted candidate, in order (``stalled``)."""
        self._order = self._collocation_order()
        self._conic: scp.ConicCall | None = None
        self._limit = 0.0
        self._problem: ConeProblem | None = None
        self.retried = False
        self.flown: tuple[ChebIterate, dict[str, Any] | None, float] | None = None
        """The reference ``flies`` flew last, its verification report and wall seconds."""
        self.extra: dict[str, Any] = {
            "legs": self.segments.leg_count,
            "intervals": self.segments.count,
            "interval_degrees": list(self.segments.degrees),
            "planet_model": model,
        }

    # -- set-up ------------------------------------------------------------------------
    def _setup(self) -> Setup:
        p, sc = self.problem, self.problem.scales
        lam_min, lam_max = self.lift_range
        terminal = []
        for j, key in POINT_MASS.terminal_states():
            t = p.terminal[key]
            if t.kind == "fixed":
                terminal.append(TerminalBound(j, float(t.value or 0.0), float(t.value or 0.0)))
            elif t.kind == "range":
                terminal.append(TerminalBound(j, float(t.lo or 0.0), float(t.hi or 0.0)))
        waypoints = [
            Waypoint(
                int(self.segments.joints[i]),
                w.latitude,
                w.longitude,
                w.radius * WAYPOINT_MARGIN,
                1.0 if self.model == "flat" else math.cos(w.latitude),
            )
            for i, w in enumerate(p.waypoints)
        ]
        obj_time, obj_heat = 0.0, 0.0
        obj_state: dict[int, float] = {}
        terms = list(p.objective)
        units = [HEAT_LOAD_UNIT if t.name == "min_heat_load" else 1.0 for t in terms]
        for term, w in zip(terms, term_pulls([t.weight for t in terms], units), strict=True):
            if term.name == "min_time":
                obj_time += w * sc.time_s
            elif term.name == "min_heat_load":
                obj_heat += w * sc.time_s / HEAT_LOAD_UNIT
            elif term.name == "max_terminal_velocity":
                obj_state[V] = obj_state.get(V, 0.0) - w * sc.speed_m_s
            elif term.name.endswith("final_latitude"):
                sign = -1.0 if term.name.startswith("max") else 1.0
                obj_state[PH] = obj_state.get(PH, 0.0) + sign * w * 180.0 / math.pi
            elif term.name.endswith("final_longitude"):
                sign = -1.0 if term.name.startswith("max") else 1.0
                obj_state[TH] = obj_state.get(TH, 0.0) + sign * w * 180.0 / math.pi
        final: tuple[float | None, float | None] = (None, None)
        if p.final_time is not None:
            final = (p.final_time, p.final_time)
        elif p.final_time_max is not None:
            final = (None, p.final_time_max)
        return Setup(
            units=self.units,
            lam2=(lam_min * lam_min, lam_max * lam_max),
            tan_bank=(math.tan(p.bank_min), math.tan(p.bank_max)),
            terminal=terminal,
            waypoints=waypoints,
            objective_time=obj_time,
            objective_state=obj_state,
            objective_heat=obj_heat,
            weight=self.options.weight_virtual_control,
            final_time=final,
            lift_weight=self.options.weight_induced_drag,
            unused_lift_weight=self.options.weight_unused_lift,
            bank_rate_max=p.bank_rate_max,
        )

    # -- driver hooks -------------------------------------------------------------------
    def start(self) -> ChebIterate:
        """The route guess, the caller's guess, or the constant-control flight."""
        p, o = self.problem, self.options
        tf = o.final_time_guess_s / p.scales.time_s if o.final_time_guess_s else None
        if p.final_time is not None:
            tf = p.final_time
        if p.guess is not None:
            return guess_start(p, self.segments)
        if self.route is not None and tf is None:
            guided = guided_start(p, self.segments, self.route, self.model)
            if guided is not None:
                return guided
        if self.route is not None and len(self.route) > 2:
            return route_start(p, self.segments, self.route, self.model, tf)
        point = objective_point(p) if self.route is None and tf is None else None
        if point is not None:  # a glide steered the way the objective pays
            start = (float(p.y0[PH]), float(p.y0[TH]))
            steered = guided_start(p, self.segments, [start, point], self.model, reach=False,
                                   gain=OBJECTIVE_STEERING_GAIN)  # fmt: skip
            if steered is not None:
                return steered
        target = self.route[-1] if self.route is not None else None
        return propagated_start(p, self.segments, self.model, tf, target)

    def linearize(self, reference: ChebIterate) -> ChebLinearization:
        """The linearization about ``reference``."""
        return linearize(self.problem, self.segments, reference, self.model)

    def subproblem(
        self, reference: ChebIterate, linearization: ChebLinearization, iteration: int
    ) -> ConeProblem:
        """Problem P2 about the reference, the path rows at the (grown) violated set."""
        margin = math.log(1.0 - self.options.path_margin) if self.options.path_margin else 0.0
        self.path_set |= linearization.path.g > margin
        if self.problem.bank_rate_max is not None:
            near = (1.0 - self.options.path_margin) * self.problem.bank_rate_max
            self.rate_set |= np.abs(linearization.bank_rate) > near
        if self.objective_bound is not None:
            room = self.objective_bound - self.plain_objective(reference, linearization)
            self.setup.objective_room = room
        problem, self.cols = build(
            self.problem,
            self.segments,
            self.setup,
            reference,
            linearization,
            self.path_set,
            self.box * self.trust.size,
            self.rate_set,
        )
        self.q = problem.q
        return problem

    def solve(
        self, problem: ConeProblem, conic: scp.ConicCall, limit_s: float, deadline: float
    ) -> ConicSolution:
        """One conic solve (the call and the problem are kept for a second-order correction);
        a solve that stalls numerically is retried once with the step regularization ten times
        heavier, which the interior-point solver has always resolved."""
        self._conic, self._limit, self._problem = conic, limit_s, problem
        solution = conic(problem, limit_s)
        self.retried = False
        if solution.status.usable or solution.status == ConicStatus.TIME_LIMIT:
            return solution
        assert problem.P is not None
        heavier = ConeProblem(problem.P * RETRY_REGULARIZATION, problem.q, problem.A, problem.b,
                              problem.cones)  # fmt: skip
        self.retried = True
        self._problem = heavier
        return conic(heavier, max(limit_s - solution.solve_time_s, 0.1))

    def _collocation_order(self) -> Array:
        """For each collocation row of the subproblem (interval, state, point), its entry in
        the flattened (defect row, state) defects."""
        order: list[int] = []
        row = 0
        for n in self.segments.degrees:
            for j in range(6):
                order += [6 * (row + i) + j for i in range(n)]
            row += n
        return np.asarray(order, dtype=np.int64)

    def _second_order(
        self, reference: ChebIterate, x: Array, lin: ChebLinearization
    ) -> Array | None:
        """A second-order correction of step ``x`` (Nocedal & Wright, Numerical Optimization,
        sec. 18.3): the subproblem again with the collocation rows shifted by the defects'
        second-order remainder at the candidate, against the Maratos effect of the exact L1
        penalty (tangential steps whose defects are second order rejected). None when the
        corrected subproblem is not solved."""
        assert self.cols is not None and self._problem is not None
        cp = self._problem
        rows = (self.segments.state_points - 1) * 6
        linear = x.copy()
        linear[self.cols.nu : self.cols.slack] = 0.0
        predicted = cp.A[:rows] @ linear - cp.b[:rows]
        actual = (lin.defects / self.units.y[None, :]).ravel()[self._order]
        b = cp.b.copy()
        b[:rows] -= actual - predicted
        corrected = ConeProblem(cp.P, cp.q, cp.A, b, cp.cones)
        assert self._conic is not None
        solution = self._conic(corrected, self._limit)
        if not solution.status.usable or solution.x is None:
            return None
        return solution.x

    def propose(
        self,
        reference: ChebIterate,
        linearization: ChebLinearization,
        solution: ConicSolution,
        iteration: int,
    ) -> scp.Proposal[ChebIterate]:
        """The candidate, its penalized cost and the record."""
        assert solution.x is not None and self.cols is not None and self.q is not None
        x = solution.x
        assert self._problem is not None
        self.merit_weight = merit_weight_of(
            solution, self._problem, self.cols, self.setup.weight, len(self.setup.terminal)
        )  # the ratio test's merit, so the reference's cost is taken here, not with the build
        self.ref_cost = self.penalized(reference, linearization)
        new, lin, cost = self._candidate(reference, x)
        predicted = self.model_cost(reference, linearization, x)
        corrected = False
        if self.ref_cost - cost < RATIO.shrink * (self.ref_cost - predicted):
            x2 = self._second_order(reference, x, lin)
            if x2 is not None:
                new2, lin2, cost2 = self._candidate(reference, x2)
                if cost2 < cost:
                    x, new, lin, cost, corrected = x2, new2, lin2, cost2, True
        dy, dT = new.y - reference.y, new.T - reference.T
        virtual = float(np.max(np.abs(x[self.cols.nu : self.cols.slack]), initial=0.0))
        change = np.max(np.abs(dy), axis=0)
        small = bool(np.all(change <= self.tol) and np.all(np.abs(dT) <= self.tol_t))
        violations = self.violations(new, lin)
        infeasibility = float(np.max(violations, initial=0.0))
        violation = float(np.sum(violations))
        small = small and infeasibility <= FEASIBLE
        u = new.u
        gap = float(np.max(u[:, 2] - u[:, 0] ** 2 - u[:, 1] ** 2))
        sc = self.problem.scales
        terms = self.term_values(new, lin)
        record = IterationRecord(
            iteration=iteration,
            cost=next(iter(terms.values())) if len(terms) == 1 else self.objective(new, lin),
            cost_terms={**terms, "final_time_s": float(np.sum(new.T)) * sc.time_s},
            objective_value=None,
            max_state_change=POINT_MASS.deltas_to_si(change, sc),
            trust_region_slack=self._squared_step(dy, new.u - reference.u, dT),
            virtual_control_norm=float(np.sum(np.abs(x[self.cols.nu : self.cols.slack]))),
            linearization_error=float(np.max(np.abs(lin.defects) / self.units.y)),
            nodes_post_corrected=None,
            relaxation_gap=gap,
            subproblem_cost=predicted,
            extra={
                "trust_radius": self.trust.size,
                "path_points": int(np.count_nonzero(self.path_set.any(axis=1))),
                "path_rows": int(np.count_nonzero(self.path_set)),
                "bank_rate_points": int(np.count_nonzero(self.rate_set)),
                "infeasibility": infeasibility,
                "violation_sum": violation,
                "leg_durations_s": [
                    float(np.sum(new.T[self.segments.leg_intervals(leg)])) * sc.time_s
                    for leg in range(self.segments.leg_count)
                ],
                "final_time_change_s": float(np.sum(dT)) * sc.time_s,
                "second_order_correction": corrected,
                "regularized_retry": self.retried,
                **({"lift_law": self.law} if self.law != "polar" else {}),
            },
            **solver_fields(solution),
        )
        self.pending = _Pending(lin, cost, predicted, small, virtual)
        return scp.Proposal(new, record)

    def _squared_step(self, dy: Array, du: Array, dT: Array) -> float:
        """The step's squared length in trust units (states, lift vector, durations)."""
        u = self.units
        parts = (dy / u.y[None, :], du / u.u[None, :], dT / u.t)
        return float(sum(np.sum(p**2) for p in parts))

    def model_cost(self, reference: ChebIterate, lin: ChebLinearization, x: Array) -> float:
        """The merit of step ``x`` as the subproblem models it: the linearized objective and the
        merit's weight on the virtual control and slacks the step leaves."""
        assert self.cols is not None and self.q is not None
        elastic = float(np.sum(x[self.cols.nu : self.cols.n]))
        du = step_of(x, self.cols, self.units, self.segments)[1]
        return (
            self.objective(reference, lin)
            + float(self.q @ x)
            + smoothing(self.setup, du, self.cols.scale)  # the quadratic part of the term
            - (self.setup.weight - self.merit_weight) * elastic
        )

    def _candidate(
        self, reference: ChebIterate, x: Array
    ) -> tuple[ChebIterate, ChebLinearization, float]:
        """The reference moved by solution ``x``, its linearization and penalized cost."""
        assert self.cols is not None
        dy, du, dT = step_of(x, self.cols, self.units, self.segments)
        new = ChebIterate(reference.y + dy, reference.u + du, reference.T + dT)
        lin = linearize(self.problem, self.segments, new, self.model)
        return new, lin, self.penalized(new, lin)

    def judge(
        self, reference: ChebIterate, proposal: scp.Proposal[ChebIterate]
    ) -> scp.Judgement[ChebIterate, ChebLinearization]:
        """SCvx's ratio test and trust-box update."""
        pend = self.pending
        assert pend is not None and self.ref_cost is not None
        ratio = step_ratio(self.ref_cost, pend.cost, pend.predicted, STATIONARY)
        record = proposal.record
        record.extra.update(ratio.describe())
        verdict = RATIO.verdict(ratio.value)
        if verdict is Verdict.REJECT:  # a stationary reference's ratio is 1: never rejected
            self.trust.shorten()
            record.extra["accepted"] = False
            return scp.Judgement(False)
        if verdict is Verdict.SHRINK:
            self.trust.shorten()
        elif verdict is Verdict.GROW:
            self.trust.lengthen()
        record.extra["accepted"] = True
        stalled = self.stalled(
            float(record.extra["infeasibility"]), float(record.extra["violation_sum"])
        )
        if stalled is not None:
            largest = self.largest_violation(proposal.reference, pend.lin)
            stalled = f"{stalled}, the largest at {largest}"
            record.extra["infeasibility_stalled"] = True
        small = pend.small
        if small and self.objective_bound is None and self._breaks_ties(pend.lin, proposal, record):
            small, stalled = False, None  # converged, unflyable: the tie-breaking phase
            self.infeasibility_trail.clear()
            self.converged = _Converged(proposal.reference, pend.lin, pend.virtual, record)
        ended = self._tie_breaking_ended(record, small, stalled)
        if ended is not None:
            return ended
        return scp.Judgement(
            True,
            small=small,
            virtual_control=pend.virtual,
            linearization=pend.lin,
            stalled=stalled,
        )

    def _tie_breaking_ended(
        self, record: IterationRecord, small: bool, stalled: str | None
    ) -> scp.Judgement[ChebIterate, ChebLinearization] | None:
        """The return to the converged answer when the tie-breaking phase has stalled or makes
        no progress (``PHASE_WINDOW``; None while it goes on): the run ends converged there, and
        the result reports how that answer flies, not an infeasibility of the phase's own
        rows. The last record then carries the kept answer's virtual control,
        relaxation gap and defect (the phase's own under ``extra.phase``): the result judges
        and diagnoses the reported answer by them."""
        start = self.converged
        if start is None or small or record is start.record:
            return None
        trail = self.phase_trail
        trail.append(float(record.extra["infeasibility"]))
        progressing = (
            len(trail) <= PHASE_WINDOW or trail[-1] < PHASE_PROGRESS * trail[-1 - PHASE_WINDOW]
        )
        if stalled is None and progressing:
            return None
        why = (
            "stalled"
            if stalled is not None
            else (
                f"its infeasibility {trail[-1]:.3g} against {trail[-1 - PHASE_WINDOW]:.3g} "
                f"{PHASE_WINDOW} accepted steps before"
            )
        )
        record.extra["tie_breaking_ended"] = (
            f"{why}: the converged answer of iteration {start.record.iteration} is kept"
        )
        kept = start.record
        record.extra["phase"] = {
            "virtual_control_norm": record.virtual_control_norm,
            "relaxation_gap": record.relaxation_gap,
            "linearization_error": record.linearization_error,
        }
        record.virtual_control_norm = kept.virtual_control_norm
        record.relaxation_gap = kept.relaxation_gap
        record.linearization_error = kept.linearization_error
        return scp.Judgement(
            True,
            small=True,
            virtual_control=start.virtual,
            reference=start.reference,
            linearization=start.lin,
        )

    def _breaks_ties(
        self, lin: ChebLinearization, proposal: scp.Proposal[ChebIterate], record: IterationRecord
    ) -> bool:
        """Whether a converged answer goes on in the tie-breaking phase: when its controls do
        not fly as planned, the lift vector is smoothed and the objective held at its converged
        value by an exact penalty (so that the smoothing only picks among equal answers); where
        the relaxed cone is slack and its unflown lift would move the flight, the lift vector
        also goes on its manifold (at the full smoothing weight, else at ``RELAXED_SMOOTHING``
        of it, below what the unused lift's weight holds)."""
        it, smooth = proposal.reference, self.options.weight_lift_smoothing
        manifold = (
            self.options.lift_manifold
            and (record.relaxation_gap or 0.0) > GAP_SWITCH
            and self._drifts(it, lin, record)
        )
        if not (manifold or smooth) or self.flies(it, record):
            return False
        self.setup.on_manifold = manifold
        self.setup.smooth_weight = smooth if manifold else RELAXED_SMOOTHING * smooth
        # the converged objective bounds the phase's: the smoothing only breaks ties
        self.objective_bound = self.plain_objective(it, lin)
        record.extra["lift_manifold"] = manifold
        record.extra["lift_smoothing"] = self.setup.smooth_weight
        return True

    def flies(self, it: ChebIterate, record: IterationRecord) -> bool:
        """Whether ``it``'s controls, flown through the full dynamics as the result's
        verification flies them, meet the problem (recorded as ``relaxed_answer_flies``)."""
        start = time.perf_counter()
        try:
            report = verify(self.verified, self.trajectory(it))
        except (ValueError, FloatingPointError, ArithmeticError):
            report = None
        self.flown = (it, report, time.perf_counter() - start)
        feasible = report is not None and bool(report["feasible"])
        record.extra["relaxed_answer_flies"] = feasible
        return feasible

    def flown_report(self, reference: ChebIterate) -> tuple[dict[str, Any], float] | None:
        """The verification report of ``reference`` and its wall seconds when ``flies`` flew it
        (the run's last converged answer), for the result: it is not flown twice."""
        if self.flown is None or self.flown[0] is not reference or self.flown[1] is None:
            return None
        return self.flown[1], self.flown[2]

    def _drifts(self, it: ChebIterate, lin: ChebLinearization, record: IterationRecord) -> bool:
        """Whether the unflown lift could move the flight (``DRIFT_SWITCH``; recorded)."""
        drift = self.unflown_drift(it, lin)
        record.extra["unflown_drift"] = drift
        return drift > DRIFT_SWITCH

    def unflown_drift(self, it: ChebIterate, lin: ChebLinearization) -> float:
        """How far the flight drifts, at most and to first order, from the lift the vehicle
        cannot leave unused: the rates' change from each point's lift vector to the one the
        verification flies (its direction at the full share of its length, within the lift
        range, with that share's drag), integrated over the flight, in trust units (1 km,
        0.5 deg, 50 m/s, ...), the largest over the states."""
        u = it.u
        norm = np.hypot(u[:, 0], u[:, 1])
        some = norm > 1e-12
        safe = np.where(some, norm, 1.0)
        lam = np.clip(norm, *self.lift_range)
        flown = np.column_stack(
            [lam * np.where(some, u[:, 0] / safe, 1.0), lam * np.where(some, u[:, 1] / safe, 0.0),
             lam * lam]
        )  # fmt: skip
        change = np.abs(np.einsum("qjk,qk->qj", lin.B, flown - u))
        total = np.zeros(6)
        for s in range(self.segments.count):
            ctrl = self.segments.controls_of(s)
            total += 0.5 * float(it.T[s]) * (self.segments.quadrature(s) @ change[ctrl])
        return float(np.max(total / self.units.y))

    def stalled(self, infeasibility: float, violation: float) -> str | None:
        """Why the run should stop when the sum of the scaled defects and excesses stayed within
        ``STALL_SHARE`` of itself over the last ``STALL_ITERATIONS`` accepted steps while the
        largest of them stays above ``FEASIBLE`` (a stationary point of the penalized cost that
        the constraints do not meet: more iterations only creep the objective); None while the
        sum still moves (its largest term may stall while the others fall)."""
        trail = self.infeasibility_trail
        trail.append(violation)
        if len(trail) <= STALL_ITERATIONS or infeasibility <= FEASIBLE:
            return None
        window = trail[-1 - STALL_ITERATIONS :]
        if max(window) - min(window) > STALL_SHARE * violation:
            return None
        return (
            f"stopped at accepted step {len(trail)}: the scaled defects and excesses (sum "
            f"{violation:.4g}, largest {infeasibility:.4g}) stayed within {STALL_SHARE:g} of "
            f"their sum over the last {STALL_ITERATIONS} accepted steps"
        )

    # -- costs ------------------------------------------------------------------------
    def plain_objective(self, it: ChebIterate, lin: ChebLinearization) -> float:
        """The problem's own objective in the subproblem's units on ``it``, without the
        tie-breakers."""
        st = self.setup
        value = st.objective_time * float(np.sum(it.T))
        for j, w in st.objective_state.items():
            value += w * float(it.y[-1, j])
        if st.objective_heat:
            value += st.objective_heat * self._heat_load(it, lin)
        return value

    def objective(self, it: ChebIterate, lin: ChebLinearization) -> float:
        """The objective in the subproblem's units on ``it``: the problem's own and the
        tie-breakers (induced drag, unused lift, the tie-breaking phase's smoothing)."""
        st = self.setup
        value = self.plain_objective(it, lin)
        if st.lift_weight and not st.fixed_lift:
            for s in range(self.segments.count):
                ctrl = self.segments.controls_of(s)
                value += st.lift_weight * float(self.segments.quadrature(s) @ it.u[ctrl, 2])
        if st.unused_lift_weight and st.fixed_lift:
            unused = 1.0 - np.hypot(it.u[:, 0], it.u[:, 1])
            value += st.unused_lift_weight * float(np.sum(unused))
        return value + smoothing(st, it.u, self.cols.scale if self.cols else 1.0)

    def _heat_load(self, it: ChebIterate, lin: ChebLinearization) -> float:
        """Integral of the heat rate (W/m^2 x nondimensional time), Clenshaw-Curtis."""
        total = 0.0
        for s in range(self.segments.count):
            ctrl = self.segments.controls_of(s)
            total += 0.5 * float(it.T[s]) * float(self.segments.quadrature(s) @ lin.heat[ctrl])
        return total

    def violations(self, it: ChebIterate, lin: ChebLinearization) -> Array:
        """Every scaled defect magnitude and excess the penalty counts."""
        return np.concatenate([values for _, values in self.labelled_violations(it, lin)])

    def labelled_violations(
        self, it: ChebIterate, lin: ChebLinearization
    ) -> list[tuple[str, Array]]:
        """The scaled defects and excesses by what they violate (the dynamics, a path limit,
        the bank rate, a zone, a waypoint, a terminal condition), in ``violations``' order."""
        parts = [
            (
                "the dynamics (collocation defects)",
                np.abs(lin.defects).ravel() / np.tile(self.units.y, lin.defects.shape[0]),
            )
        ]
        if self.path_set.any():
            parts.append(("a path limit", np.maximum(lin.path.g[self.path_set], 0.0) / PATH_UNIT))
        if self.rate_set.any():
            assert self.problem.bank_rate_max is not None
            share = np.abs(lin.bank_rate[self.rate_set]) / self.problem.bank_rate_max - 1.0
            parts.append(("the bank-rate limit", np.maximum(share, 0.0) / PATH_UNIT))
        for k, (zone, zl) in enumerate(zip(self.problem.no_fly_zones, lin.zones, strict=True)):
            parts.append((f"no-fly zone {k}", np.maximum(zone.radius - zl.c, 0.0) / ZONE_UNIT))
        for k, w in enumerate(self.setup.waypoints):
            d = math.hypot(
                it.y[w.point, PH] - w.latitude, w.lon_factor * (it.y[w.point, TH] - w.longitude)
            )
            parts.append((f"waypoint {k}", np.array([max(d - w.radius, 0.0) / ZONE_UNIT])))
        if self.setup.on_manifold:
            gap = it.u[:, 2] - it.u[:, 0] ** 2 - it.u[:, 1] ** 2
            parts.append(("the lift vector's length (u3 = u1^2 + u2^2)", np.abs(gap) / GAP_UNIT))
        last = it.y[-1]
        names = dict(POINT_MASS.terminal_states())
        for t in self.setup.terminal:
            j = t.state
            excess = max(last[j] - t.hi, t.lo - last[j], 0.0) / self.units.y[j]
            parts.append((f"the terminal {names.get(j, j)}", np.array([excess])))
        return parts

    def largest_violation(self, it: ChebIterate, lin: ChebLinearization) -> str:
        """What the largest scaled defect or excess violates."""
        parts = self.labelled_violations(it, lin)
        return max(parts, key=lambda part: float(np.max(part[1], initial=0.0)))[0]

    def infeasibility(self, it: ChebIterate, lin: ChebLinearization) -> float:
        """The largest scaled defect or excess."""
        return float(np.max(self.violations(it, lin), initial=0.0))

    def penalized(self, it: ChebIterate, lin: ChebLinearization) -> float:
        """Objective + weight x the L1 norm of the defects and excesses (the merit function)."""
        value = self.objective(it, lin) + self.merit_weight * float(
            np.sum(self.violations(it, lin))
        )
        if self.objective_bound is not None and self.cols is not None:
            excess = self.plain_objective(it, lin) - self.objective_bound
            value += self.merit_weight * max(excess, 0.0) / (BOUND_UNIT * self.cols.scale)
        return value

    # -- results ----------------------------------------------------------------------
    def term_values(self, it: ChebIterate, lin: ChebLinearization) -> dict[str, float]:
        """Each objective term's value (SI: s, m/s, deg, J/m^2) on ``it``."""
        sc = self.problem.scales
        values: dict[str, float] = {}
        for term in self.problem.objective:
            if term.name == "min_time":
                values[term.name] = float(np.sum(it.T)) * sc.time_s
            elif term.name == "max_terminal_velocity":
                values[term.name] = float(it.y[-1, V]) * sc.speed_m_s
            elif term.name.endswith("final_latitude"):
                values[term.name] = math.degrees(float(it.y[-1, PH]))
            elif term.name.endswith("final_longitude"):
                values[term.name] = math.degrees(float(it.y[-1, TH]))
            elif term.name == "min_heat_load":
                values[term.name] = self._heat_load(it, lin) * sc.time_s
        return values

    def trajectory(self, reference: ChebIterate) -> OptimizedTrajectory:
        """The state points as a time trajectory, bank and lam as the method represents them."""
        p = self.problem
        alpha_ctrl, alpha_range = None, None
        if self.law == "share":  # the angle of attack of each point's lift share, at its Mach
            lam = np.clip(np.hypot(reference.u[:, 0], reference.u[:, 1]), *self.lift_range)
            alpha_ctrl = alpha_of_share(p, reference.y[self.segments.state_of_control], lam)
            assert p.alpha_range is not None
            alpha_range = (math.degrees(p.alpha_range[0]), math.degrees(p.alpha_range[1]))
        path = LiftVectorPath(
            self.segments, reference.T.copy(), reference.u.copy(),
            (p.bank_min, p.bank_max), self.lift_range, alpha_ctrl, alpha_range,
        )  # fmt: skip
        t = self.segments.times(reference.T)
        bank, lam_or_alpha = path.at(t)
        # a scheduled vehicle's angle of attack is its schedule's, which the result reads
        alpha = None if self.law == "schedule" else lam_or_alpha
        return OptimizedTrajectory(
            "time", t, reference.y.copy(), t, bank, alpha_deg=alpha, attitude=path
        )

    def objective_terms(self, outcome: scp.ScpOutcome[ChebIterate]) -> dict[str, float]:
        """Each term's value (SI) on the last reference."""
        ref = outcome.reference
        if ref is None:
            return {}
        return self.term_values(ref, self.linearize(ref))


def merit_weight_of(
    solution: ConicSolution, problem: ConeProblem, cols: Columns, weight: float, terminal: int
) -> float:
    """The merit's penalty weight for a step: ``MERIT_MARGIN`` times the largest multiplier of
    a row the subproblem relaxes, within [``MERIT_FLOOR`` x ``weight``, ``weight``]: of the
    defect, path, bank-rate, zone and waypoint rows ``weight`` less the reduced cost of the
    row's elastic column; of a terminal bound (its two rows, from ``cols.terminal_rows`` of the
    nonnegative block, share one slack) the difference of the two rows' multipliers, which is
    the bound's own (their sum is not, and a fixed value's is large on the central path).
    The subproblem's own weight keeps its virtual control off; a merit that weighs the
    second-order defects of every step a thousand times the objective stalls the trust box at
    steps whose defects cancel their predecessors', where the multipliers say they are worth
    far less. ``weight`` when the solver reports no multipliers."""
    if solution.y is None:
        return weight
    y, first = solution.y, problem.cones.n_zero
    reduced = y[first : first + cols.n - cols.nu - terminal]
    largest = float(np.max(weight - reduced, initial=0.0))
    if terminal:
        start = first + cols.terminal_rows
        pairs = y[start : start + 2 * terminal].reshape(terminal, 2)
        largest = max(largest, float(np.max(np.abs(pairs[:, 0] - pairs[:, 1]))))
    return min(weight, max(MERIT_MARGIN * largest, MERIT_FLOOR * weight))


def lift_range(problem: EntryProblem) -> tuple[float, float]:
    """The range of lam: a polar's normalized lift or a lift share's (``lift_share``), or (1, 1)
    for a scheduled vehicle, whose lam is the share of its schedule's lift flown (all of it)."""
    return problem.lift_range if problem.lift_range is not None else (1.0, 1.0)


def run(problem: EntryProblem, options: ChebScvxOptions, **hooks: Unpack[RunHooks]) -> MethodResult:
    """Run paper 001's Chebyshev SCvx on ``problem`` with its ``options`` (an optimized angle of
    attack flown as a lift share)."""
    flown = share_problem(problem)
    return run_method(
        lambda: ChebScvx(flown, options, problem.planet_model, problem), options, hooks
    )
