"""Time-domain SCP with exact FOH discretization and an adaptive grid (paper 002, Algorithm 1),
as hooks of the shared driver (``scp.loop``).

Each iteration solves Problem 2 (a QP) about the reference with the penalized trust region and,
by default, the Lagrangian curvature of the interval maps (an SQP step); its solution is the
candidate, whose own discretization gives the step's defect (nodes minus their propagation).
The defect adapts the trust weight (``scp.trust.DefectTrustWeight``; paper 002 keeps it fixed),
a step whose propagation leaves the models' range is rejected, and a step is small only when
no node, bank angle or interval length moved more than its tolerance, the defect is within the
stop tolerance, the objective has settled and the trust weight is not above its initial value
(a step kept small by a heavy trust weight is not a converged one).
"""

from __future__ import annotations

import functools
import math
import time
from concurrent.futures import Future
from dataclasses import dataclass, field
from typing import Any, Unpack

import numpy as np

from app.schemas.methods import FohPtrOptions
from worker.solver import side_thread
from worker.solver.conic import ConeProblem, ConicSolution
from worker.solver.methods.base import MethodResult, RunHooks, run_method, run_starts
from worker.solver.methods.foh_ptr.alpha_state import (
    alpha_bounds,
    held_alpha,
    held_alpha_problem,
    held_start,
    held_trajectory,
)
from worker.solver.methods.foh_ptr.linearizer import Linearizer, defect, finite
from worker.solver.methods.foh_ptr.records import iteration_record
from worker.solver.methods.foh_ptr.support import grid_factor, interval_bounds
from worker.solver.models.bank_state_compiled import compiled_parameters
from worker.solver.problem import EntryProblem
from worker.solver.scp import loop as scp
from worker.solver.scp.trust import DefectTrustWeight
from worker.solver.trajectory import OptimizedTrajectory
from worker.solver.transcription.foh_data import GridLimits, SubproblemData
from worker.solver.transcription.foh_model import foh_model
from worker.solver.transcription.foh_subproblem import FohSubproblem
from worker.solver.transcription.terminal import terminal_rows
from worker.solver.transcription.time_grid import (
    InitialGuessError,
    Reference,
    free_time_span,
    guess_reference,
    initial_reference,
    sign_start_banks,
)
from worker.solver.warmup import warm_up

Array = np.ndarray
Linearization = tuple[SubproblemData, Array]
"""The subproblem data about a reference and the path-limit ratios at its nodes."""

DIFFERENCE_STEP = 1e-5
"""Step of the Hessian's forward differences in scaled subproblem units (1 cm of altitude, about
0.02 m/s of speed): truncation error ~1e-5 relative, rounding ~1e-11."""

INTERVAL_SCALE_S = 10.0
"""Unit of the scaled interval changes at paper 002's mean interval (1600 s / 39), scaled with
the mean interval: a unit step moves a node about as far whatever the node count."""


@dataclass
class FohIterate:
    """A reference: nodes z (K, nz), rates w (K,) or (K, 2) with an angle-of-attack state,
    interval lengths s (K-1,), the dynamics rows' multipliers of the subproblem that made it,
    and the objective terms on it (SI)."""

    z: Array
    w: Array
    s: Array
    multipliers: Array | None = None
    values: dict[str, float] = field(default_factory=dict)


@dataclass
class _Pending:
    """What judging a proposal needs beyond its record: the candidate's linearization and the
    step's size, direction and costs."""

    linearization: Linearization
    weight: float
    small: bool
    virtual: float
    cost: float
    step: Array
    reversal: float


class FohPtr:
    """Paper 002's method on the driver: linearize, build, propose, judge (``scp.loop``)."""

    def __init__(
        self, problem: EntryProblem, options: FohPtrOptions, start_bank_deg: float | None = None
    ) -> None:
        self.problem, self.options = problem, options
        self.start_bank_deg = options.initial_bank_deg if start_bank_deg is None else start_bank_deg
        self.model = foh_model(problem)
        layout = self.model.layout
        sc = problem.scales
        self.scale = layout.trust_units(sc)
        self.lin = Linearizer(problem, options, self.scale)
        self.first: Reference | InitialGuessError = self._first_reference()
        span = (
            problem.final_time
            if problem.final_time is not None
            else free_time_span(problem, self.first)
        )
        span_s = span * sc.time_s
        lo, hi, trust = interval_bounds(options, span_s)
        if options.grid == "uniform" and problem.final_time is None:
            raise ValueError("a free final time needs the adaptive grid")
        grid = (
            GridLimits(
                delta_min=lo / sc.time_s,
                delta_max=hi / sc.time_s,
                delta_trust=trust / sc.time_s,
                final_time=problem.final_time,
                final_time_max=problem.final_time_max,
            )
            if options.grid == "adaptive"
            else None
        )
        lin = self.lin
        self.sub = FohSubproblem(
            options.nodes,
            state_scale=self.scale,
            rate_scale=math.radians(1.0) * sc.time_s,
            interval_scale=INTERVAL_SCALE_S * grid_factor(options, span_s) / sc.time_s,
            n_initial=lin.initial.size,
            terminal=terminal_rows(
                problem,
                layout,
                fixed="virtual",
                virtual_weight=options.weight_virtual_control,
                trust_units=self.scale,
            ),
            bank_max=problem.bank_max,
            bank_min=problem.bank_min,
            bank_rate_max=problem.bank_rate_max,
            n_limits=len(lin.limits),
            n_zones=len(problem.no_fly_zones),
            grid=grid,
            n_inner_rows=len(lin.limits) + len(problem.no_fly_zones) if lin.inner_on else 0,
            weight_trust_region=options.weight_trust_region,
            weight_trust_interval=options.weight_trust_interval,
            weight_trust_final_time=options.weight_trust_final_time,
            weight_buffer=options.weight_virtual_control,
            hessian_blocks=lin.second_order,
            identity_e=options.discretization == "exact_foh",
            layout=layout,
            controls=self.model.controls,
            initial_states=lin.initial_states,
            alpha=alpha_bounds(problem, self.model.alpha),
        )
        lin.difference_steps = DIFFERENCE_STEP * self.sub.block_scale
        lin.blocks = self.sub.curvature_layout
        tol = options.stop_tolerance
        self.tol_z = layout.deltas_from_si(tol, sc)
        self.tol_s = tol.interval_s / sc.time_s
        self.trust = DefectTrustWeight(
            initial=options.weight_trust_region,
            minimum=options.weight_trust_region_min,
            defect_target=options.trust_defect_target,
            factor=options.trust_factor,
            reversal_cosine=options.trust_reversal_cosine,
        )
        self.extra: dict[str, Any] = {}
        self.prev_cost: float | None = None
        self.pending: _Pending | None = None
        self.second_order = False  # whether the last subproblem carried the curvature
        self.it_start = time.perf_counter()
        # The curvature of a new reference needs only the reference and the multipliers: with
        # a second CPU it is integrated and convexified on the helper thread while this one
        # discretizes the same reference (the kernels release the GIL); otherwise in line.
        self.overlap = lin.second_order and side_thread.available()
        self.curvature: Future[Array | None] | None = None

    def start(self) -> FohIterate:
        """The caller's initial guess on the grid, else the constant-bank reference that best
        meets the terminal conditions."""
        ref = self.first
        if isinstance(ref, InitialGuessError):  # the method cannot start: a failed job
            raise scp.StartError("initial_guess", str(ref)) from ref
        if self.problem.guess is not None:  # the caller's earlier answer
            self.extra["initial_guess"] = "trajectory"
        else:
            self.extra["initial_bank_deg"] = ref.bank_deg
        if self.problem.final_time is None:
            self.extra["initial_final_time_s"] = float(np.sum(ref.s)) * self.problem.scales.time_s
        return FohIterate(ref.z, ref.w, ref.s)

    def _first_reference(self) -> Reference | InitialGuessError:
        """The initial reference (``start``), or why there is none; made at construction
        because a free final time's grid bounds scale with its flight time."""
        model, nodes = self.model, self.options.nodes
        if model.alpha is not None:  # the bank-state start flown at a held alpha
            return held_start(self.problem, model.unit, nodes, self.start_bank_deg)
        try:
            if self.problem.guess is not None:
                return guess_reference(self.problem, nodes)
            return initial_reference(self.problem, nodes, self.start_bank_deg)
        except InitialGuessError as exc:
            return exc

    def tighten(self) -> bool:
        """A heavier trust weight after the conic solver failed on the subproblem (the driver
        solves it again about the same reference); False when it is at its ceiling."""
        before = self.trust.weight
        self.trust.rejected()
        return self.trust.weight > before

    def linearize(self, reference: FohIterate) -> Linearization:
        """Subproblem data about ``reference`` (``Linearizer.data``)."""
        return self.lin.data(reference.z, reference.w, reference.s)

    def subproblem(
        self, reference: FohIterate, linearization: Linearization, iteration: int
    ) -> ConeProblem:
        """Problem 2 about ``reference``: virtual-control weight ramped up, current trust weight,
        and the curvature (from the helper thread when it overlapped)."""
        o, sub = self.options, self.sub
        self.it_start = time.perf_counter()
        sub.set_virtual_factor(
            min(o.virtual_control_growth ** (iteration - 1), 1.0e6)
            * o.weight_virtual_control_initial
            / o.weight_virtual_control
            if o.weight_virtual_control_initial < o.weight_virtual_control
            else 1.0
        )
        if sub.w_buf > o.weight_virtual_control:
            sub.set_virtual_factor(1.0)
        sub.w_tr = self.trust.weight
        if self.curvature is None:  # in line: one CPU, or a reference restored after a rejection
            z, w, s = reference.z, reference.w, reference.s
            self.curvature = side_thread.completed(
                self.lin.curvature(z, w, s, reference.multipliers)
            )
        curvature = self.curvature
        problem = sub.build(linearization[0], curvature.result)  # waits for the curvature last
        self.second_order = curvature.result() is not None
        self.curvature = None
        return problem

    def solve(
        self, problem: ConeProblem, conic: scp.ConicCall, limit_s: float, deadline: float
    ) -> ConicSolution:
        """One solve, no retry."""
        return conic(problem, limit_s)

    def propose(
        self,
        reference: FohIterate,
        linearization: Linearization,
        solution: ConicSolution,
        iteration: int,
    ) -> scp.Proposal[FohIterate]:
        """Unpack the step, start the candidate's curvature, discretize about the candidate (it
        judges the step) and record the iteration."""
        lin_s = time.perf_counter() - self.it_start
        sub, scale = self.sub, self.scale
        data, ratio = linearization
        assert solution.x is not None
        nz = scale.size
        multipliers = (
            solution.y[: sub.N * nz].reshape(sub.N, nz) / scale  # rows divided by the scale
            if self.lin.second_order and solution.y is not None
            else None
        )
        new = sub.unpack(solution.x, data)
        if self.overlap and multipliers is not None:  # the candidate's curvature, on the helper
            self.curvature = side_thread.submit(
                self.lin.curvature, new.z, new.w, new.s, multipliers
            )
        report = self.lin.report()
        candidate = self.lin.data(new.z, new.w, new.s)  # the next linearization judges this step
        assert self.lin.objective is not None
        values = self.lin.objective.values(new.z, new.s, heat_load=candidate[0].heat_load)
        step = np.concatenate([new.dz.ravel(), new.dw.ravel()])
        record, small, virtual = iteration_record(
            self,
            iteration,
            reference,
            new,
            data,
            candidate[0],
            ratio,
            report,
            values,
            solution,
            lin_s,
            step,
        )
        self.pending = _Pending(
            linearization=candidate,
            weight=self.trust.weight,
            small=small,
            virtual=virtual,
            cost=self.lin.objective.normalized(values),
            step=step,
            reversal=self.trust.reversal(step),
        )
        return scp.Proposal(FohIterate(new.z, new.w, new.s, multipliers, values), record)

    def judge(
        self, reference: FohIterate, proposal: scp.Proposal[FohIterate]
    ) -> scp.Judgement[FohIterate, Linearization]:
        """Reject a step whose propagation is not finite (back to the reference, heavier trust
        weight); else adapt the trust weight to its defect and test it for convergence."""
        pending, record = self.pending, proposal.record
        assert pending is not None
        self.pending = None
        if not finite(pending.linearization[0]):
            self.curvature = None  # of the rejected candidate: not used
            restored = self.linearize(reference)
            self.trust.rejected()
            record.extra["rejected"] = "the step's propagation left the models' range"
            return scp.Judgement(accepted=False, linearization=restored)
        by_state, step_defect = defect(pending.linearization[0], self.scale)
        self.trust.accepted(pending.step, pending.reversal, step_defect)
        record.extra["step_defect"] = step_defect
        o = self.options
        settled = self.prev_cost is not None and abs(pending.cost - self.prev_cost) <= (
            o.stop_tolerance.relative_cost * max(abs(pending.cost), 1.0)
        )
        self.prev_cost = pending.cost
        small = (
            pending.small
            and settled
            and pending.weight <= o.weight_trust_region
            and bool(np.all(by_state <= self.tol_z))
        )
        return scp.Judgement(
            accepted=True,
            small=small,
            virtual_control=pending.virtual,
            linearization=pending.linearization,
        )

    def trajectory(self, reference: FohIterate) -> OptimizedTrajectory:
        """The nodes as a time-grid trajectory, with the FOH bank rate for exact bank
        propagation."""
        t = np.concatenate([[0.0], np.cumsum(reference.s)])
        if self.model.alpha is not None:  # both attitude states held as the subproblem holds
            return held_trajectory(t, reference.z, reference.w, self.model)
        sigma = self.model.bank
        return OptimizedTrajectory(
            "time",
            t,
            reference.z[:, :sigma].copy(),
            t,
            reference.z[:, sigma].copy(),
            bank_rate=reference.w.copy(),
        )

    def objective_terms(self, outcome: scp.ScpOutcome[FohIterate]) -> dict[str, float]:
        """The terms on the last accepted reference."""
        return dict(outcome.reference.values) if outcome.reference is not None else {}


def run(problem: EntryProblem, options: FohPtrOptions, **hooks: Unpack[RunHooks]) -> MethodResult:
    """Run paper 002's SCP on ``problem`` (fixed or free final time) with its ``options``."""
    if compiled_parameters(problem.forces, problem.omega) is not None:
        warm_up()  # compile or load the kernels before the clock starts (at once when loaded)
    free_bank = (
        options.initial_bank_deg is None
        and problem.initial_bank_deg is None
        and problem.guess is None  # a guess sets the bank's sign: one start from it
    )
    swept, model = problem, foh_model(problem)
    if model.alpha is not None:  # the sweep flies the start's held alpha
        swept = held_alpha_problem(problem, held_alpha(problem, model.unit), model.unit)
    banks = sign_start_banks(swept, options.nodes) if free_bank and options.bank_sign_starts else []
    if len(banks) < 2:
        return run_method(lambda: FohPtr(problem, options), options, hooks)
    made: list[FohPtr] = []

    def build(bank: float) -> FohPtr:
        made.append(FohPtr(problem, options, bank))
        return made[-1]

    def cost(result: MethodResult) -> float:
        """The result's objective, normalized as the first start normalizes it (a heat-load
        unit comes from the guess, so each start's own would not compare)."""
        objective = next((m.lin.objective for m in made if m.lin.objective is not None), None)
        assert objective is not None  # a converged start has linearized
        return objective.normalized(result.objective_terms)

    return run_starts(
        [functools.partial(build, bank) for bank in banks],
        options,
        hooks,
        cost,
        [{"initial_bank_deg": bank} for bank in banks],
    )
