"""Energy-domain SCP with post-correction (paper 000, Jung, Kim, Choi & Lee), as hooks of the
shared driver (``scp.loop``).

Paper 000 sec. 3.4, steps 1-4: linearize the energy-form dynamics about the reference, solve the
trapezoidal SOCP (transcription.energy_trapezoid), shorten the step of every (node, state) whose
linearization error is large (post-correction, eq. 38), and stop when no state moved more than
its tolerance (eq. 37). Departures from the printed method, each a correction: the exact
V(r, e) replaces eq. 8's approximation; the trust region is scaled per state; virtual control is
added only when a subproblem is infeasible, and then penalized and reported; after two
iterations the nodes are re-spaced evenly in flight time (again when the flight time moves);
the bank step between nodes is bounded, a step is not converged while the bank chatters or the
control cone is slack (then the controls move onto the circle keeping their vertical lift); the
trust-region and regularization weights are relaxed after the first iterations (a step the
linearization does not hold is rejected and the weight stiffened) and a step is converged only
once they are and the running costs are stationary (the paper's fixed weights
creep towards the optimum and its state test stops them short); near convergence the
trapezoid is corrected by its error on each interval (transcription.energy_defect), so the
converged trajectory is the one its controls fly at any node count; fixed terminal conditions
are held by an exact L1 penalty whose miss must vanish (docs/methods/energy-scp.md).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Any, Unpack

import numpy as np

from app.schemas.methods import EnergyScpOptions
from worker.solver.conic import ConeProblem, ConicSolution, ConicStatus
from worker.solver.methods.base import MethodResult, RunHooks, run_method
from worker.solver.methods.energy_scp.controls import GAP_TOL, bank_chatter, lift_preserving
from worker.solver.methods.energy_scp.guess import (
    TIME_INDEX,
    energy_bounds,
    guess_in_energy,
    initial_guess,
)
from worker.solver.methods.energy_scp.objective import EnergyObjective
from worker.solver.methods.energy_scp.records import iteration_record
from worker.solver.methods.energy_scp.regularization import ConeRegularization
from worker.solver.models.bank_state_compiled import compiled_parameters
from worker.solver.models.layout import ENERGY
from worker.solver.models.point_mass import (
    EnergyDerivatives,
    energy_dynamics,
    energy_rates,
    time_state_from_energy,
)
from worker.solver.objectives import RUNNING_COSTS, energy_running_density, trapezoid
from worker.solver.path_limits import radius_lower_bound
from worker.solver.problem import EntryProblem
from worker.solver.scp import loop as scp
from worker.solver.scp.trust import RelaxingTrustWeight
from worker.solver.trajectory import OptimizedTrajectory
from worker.solver.transcription.energy_defect import exact_increments, trapezoid_defect
from worker.solver.transcription.energy_defect_compiled import compiled_increments
from worker.solver.transcription.energy_grid import energy_grid, time_uniform_grid
from worker.solver.transcription.energy_trapezoid import EnergyTrapezoid, SubproblemData
from worker.solver.transcription.terminal import terminal_rows

Array = np.ndarray
REGRID_AFTER = 2
"""Iteration after which the nodes are re-spaced evenly in the iterate's flight time."""
REGRID_SHIFT = 12.0
"""Re-space again when the time-even grid moved a node by more than this many mean intervals."""
DEFECT_SUBSTEPS = 8
"""RK4 steps per interval of the deferred correction (energy_defect)."""
NEAR_FACTOR = 10.0
"""The deferred correction starts once every state step is below this many tolerances."""
REJECT_ERROR = 100.0
"""A step after the held iterations whose linear model errs by more than this many trust units
on one interval is rejected: the relaxed trust weight let it leave where the linearization
holds."""
SETTLED_ITERATIONS = 2
"""Consecutive stationary iterations the stop test needs: one small cost change can be chance
(measured: the hard terminal point at 161 nodes stopped on one, +0.31 % above its optimum)."""


@dataclass
class EnergyIterate:
    """A reference (e, x, u) after post-correction, and the subproblem solution that made it
    (the trajectory reported is the solution, on its own grid)."""

    e: Array
    x: Array
    u: Array
    e_solution: Array
    x_solution: Array
    u_solution: Array


class EnergyScp:
    """Paper 000's method on the driver: linearize, build, propose, judge (``scp.loop``)."""

    def __init__(self, problem: EntryProblem, options: EnergyScpOptions) -> None:
        self.problem, self.options = problem, options
        e0, ef = energy_bounds(problem)
        self.e = energy_grid(
            e0, ef, options.nodes, "uniform" if options.grid == "uniform" else "glide_time"
        )
        self.scale = ENERGY.trust_units(problem.scales)
        self.r_ceiling = 1.0 + 200e3 / problem.scales.radius_m
        self.r_lower: Array | None = None
        self.regrid_done = 0
        self.trust = RelaxingTrustWeight(
            options.weight_trust_region,
            options.weight_trust_region_min,
            options.trust_relax_factor,
            options.trust_hold_iterations,
        )
        self.regularization = ConeRegularization(
            options.nodes,
            options.weight_regularization,
            options.weight_regularization_min,
            options.trust_hold_iterations,
        )
        self.values: dict[str, float] = {}
        self.previous_values: dict[str, float] = {}
        penalty = options.weight_terminal_penalty
        self.terminal = (
            terminal_rows(problem, ENERGY, fixed="hard")
            if penalty is None
            else terminal_rows(
                problem, ENERGY, fixed="virtual", virtual_weight=penalty, trust_units=self.scale
            )
        )
        self.tol = ENERGY.deltas_from_si(options.stop_tolerance, problem.scales)
        self.next_ed: EnergyDerivatives | None = None
        self.reference_ed: EnergyDerivatives | None = None  # the current subproblem's
        self.data: SubproblemData | None = None
        self.tr = self.transcription(options.virtual_control == "on")
        self.extra: dict[str, Any] = {}
        self.cost_correction: dict[str, float] = {}
        self.correcting = False
        self.compiled = compiled_parameters(problem.forces, problem.omega)
        """The force parameters of the compiled correction (None: the numpy form)."""
        self.corrected_from = 0  # the first iteration whose costs are the corrected ones
        self.settled = 0  # consecutive iterations over which every running cost was stationary

    def transcription(self, virtual_control: bool) -> EnergyTrapezoid:
        """The trapezoidal SOCP on the current grid, with or without virtual control."""
        o = self.options
        return EnergyTrapezoid(
            self.e,
            self.scale,
            self.terminal,
            bank_max=self.problem.bank_max,
            path_limits=self.problem.limits.any,
            virtual_control=virtual_control,
            weight_trust_region=self.trust.weight,
            weight_regularization=self.regularization.weights,
            weight_virtual_control=o.weight_virtual_control,
            weight_control_smoothness=o.weight_control_smoothness,
            bank_rate_rows=True,
        )

    def start(self) -> EnergyIterate:
        """The straight-line guess; fails when no altitude meets the path limits somewhere."""
        p, e = self.problem, self.e
        x, u = initial_guess(p, e) if p.guess is None else guess_in_energy(p, e)
        if p.limits.any:
            self.r_lower, feasible = radius_lower_bound(p.forces, p.limits, e, 1.0, self.r_ceiling)
            if not np.all(feasible):
                bad = int(np.argmin(feasible))
                raise scp.StartError(
                    "path_limits_infeasible",
                    f"no altitude satisfies the path limits at energy {e[bad]:.4f} "
                    f"(node {bad}); raise the limits or change the energy range",
                )
        self.next_ed = energy_dynamics(x, u, e, p.forces, p.omega)
        self.objective = EnergyObjective(p, e, x, self.next_ed, self.scale, self.trust.initial)
        return EnergyIterate(e, x, u, e, x, u)

    def linearize(self, reference: EnergyIterate) -> EnergyDerivatives:
        """The energy-form dynamics and their Jacobians about ``reference``."""
        ed, self.next_ed = self.next_ed, None
        if ed is not None:  # the initial guess's, computed for the objective's scales
            return ed
        p = self.problem
        return energy_dynamics(reference.x, reference.u, reference.e, p.forces, p.omega)

    def subproblem(
        self, reference: EnergyIterate, linearization: EnergyDerivatives, iteration: int
    ) -> ConeProblem:
        """The trapezoidal SOCP about ``reference`` (paper 000 Problem 3)."""
        self.reference_ed = linearization  # a rejected step is solved again about it
        run_grad, term_grad = self.objective.gradients(reference.x, linearization)
        self.data = SubproblemData(
            x_ref=reference.x,
            u_ref=reference.u,
            f=linearization.f,
            A=linearization.A,
            B=linearization.B,
            cost_gradient=run_grad,
            terminal_gradient=term_grad,
            radius_lower=self.r_lower,
            x0=self.problem.y0[list(TIME_INDEX)],
            bank_step_max=self.bank_step_max(reference.e, linearization),
            defect=self.defect(reference, linearization),
        )
        return self.tr.build(self.data)

    def defect(self, reference: EnergyIterate, ed: EnergyDerivatives) -> Array | None:
        """The trapezoid's error on each interval of ``reference`` (None when the deferred
        correction is off); keeps the running costs' exact-minus-trapezoid for ``propose``."""
        if not self.correcting:
            self.cost_correction = {}
            return None
        p, e = self.problem, reference.e
        running = [t.name for t in p.objective if t.name in RUNNING_COSTS]

        def densities(x: Array, rates: Any) -> Array:
            columns = [energy_running_density(p, name, x, rates) for name in running]
            return np.column_stack(columns) if columns else np.zeros((x.shape[0], 0))

        if self.compiled is not None:  # the same integration, compiled
            inc = compiled_increments(
                p, self.compiled, e, reference.x, reference.u, running, DEFECT_SUBSTEPS
            )
        else:
            inc = exact_increments(
                e,
                reference.x,
                reference.u,
                lambda x, u, ee: energy_rates(x, u, ee, p.forces, p.omega),
                densities,
                DEFECT_SUBSTEPS,
            )
        self.cost_correction = {
            name: float(np.sum(inc.running[:, j]))
            - trapezoid(energy_running_density(p, name, reference.x, ed), e)
            for j, name in enumerate(running)
        }
        return trapezoid_defect(e, reference.x, ed.f, inc)

    def bank_step_max(self, e: Array, ed: EnergyDerivatives) -> Array:
        """The largest bank change of each interval: ``bank_step_max_deg``, or less when the
        rate bound w over the interval's flight time dt_i on the reference (trapezoid of dt/de)
        is smaller."""
        o = self.options
        angle = np.full(e.size - 1, math.radians(o.bank_step_max_deg))
        if o.bank_rate_limit_deg_s is not None:
            dt_de = 1.0 / np.maximum(np.abs(ed.edot), 1e-12)
            dt = 0.5 * (dt_de[1:] + dt_de[:-1]) * np.diff(e)
            rate = math.radians(o.bank_rate_limit_deg_s) * self.problem.scales.time_s
            angle = np.minimum(angle, rate * dt)
        return angle

    def solve(
        self, problem: ConeProblem, conic: scp.ConicCall, limit_s: float, deadline: float
    ) -> ConicSolution:
        """One solve; an infeasible one is solved again with virtual control when it is
        ``auto``."""
        solution = conic(problem, limit_s)
        if (
            solution.status == ConicStatus.INFEASIBLE
            and self.options.virtual_control == "auto"
            and not self.tr.virtual_control
        ):
            assert self.data is not None
            self.tr = self.transcription(True)
            remaining = max(deadline - time.perf_counter(), 1e-3)
            solution = conic(self.tr.build(self.data), remaining)
        return solution

    def propose(
        self,
        reference: EnergyIterate,
        linearization: EnergyDerivatives,
        solution: ConicSolution,
        iteration: int,
    ) -> scp.Proposal[EnergyIterate]:
        """Unpack the solution and post-correct it (paper 000 eq. 38 and the state update
        algorithm): the step of each (node, state) whose linearization error exceeds the
        threshold is shortened."""
        p, o, e = self.problem, self.options, reference.e
        assert self.data is not None and solution.x is not None
        sub = self.tr.unpack(solution.x, self.data)
        # values only: the Jacobians are needed at the next reference, linearized later
        rates = energy_rates(sub.x, sub.u, e, p.forces, p.omega)
        ed, x_ref, u_ref = linearization, reference.x, reference.u
        f_lin = (
            ed.f
            + np.einsum("kij,kj->ki", ed.A, sub.x - x_ref)
            + np.einsum("kij,kj->ki", ed.B, sub.u - u_ref)
        )
        lin_err = np.abs(rates.f - f_lin) * self.tr.quad_w[:, None] / self.scale[None, :]
        corrected = np.zeros_like(lin_err, dtype=bool)
        x_next = sub.x
        if o.post_correction:
            corrected = lin_err > o.linearization_error_threshold
            corrected[0] = False
            x_next = np.where(corrected, x_ref + o.post_correction_step * (sub.x - x_ref), sub.x)
        self.change = np.max(np.abs(x_next - x_ref), axis=0)
        values = self.objective.values(sub.x, rates)
        for name, correction in self.cost_correction.items():
            values[name] += correction  # the exact quadrature where the intervals are exact
        self.previous_values, self.values = self.values, values
        record, self.virtual = iteration_record(
            self, iteration, sub, solution, values, lin_err, corrected
        )
        return scp.Proposal(EnergyIterate(e, x_next, sub.u, e, sub.x, sub.u), record)

    def judge(
        self, reference: EnergyIterate, proposal: scp.Proposal[EnergyIterate]
    ) -> scp.Judgement[EnergyIterate, EnergyDerivatives]:
        """A step after the held iterations whose linear model errs by more than
        ``REJECT_ERROR`` on an interval is rejected (``reject``); every other step is taken;
        small when no state moved more than its tolerance (eq. 37) on
        a grid that has been used once, the trust-region weight has been relaxed to its floor,
        every running cost has been stationary over ``SETTLED_ITERATIONS`` consecutive
        iterations (counted on like costs: not across the start of the deferred correction),
        the bank does not chatter and the control cone is tight (else the reference's controls
        are projected onto it and the iteration goes on).
        Then the trust and regularization weights are updated for the next subproblem.
        Not converged after ``REGRID_AFTER`` iterations, the grid is re-spaced evenly in flight
        time (which resolves the terminal maneuver that a grid even in energy crowds into its
        last intervals), and again whenever the flight time has moved (``regrid_due``)."""
        iteration = proposal.record.iteration
        if (
            iteration > self.options.trust_hold_iterations
            and proposal.record.linearization_error > REJECT_ERROR
            and self.trust.rejected()
        ):
            return self.reject(proposal)
        chatter = bank_chatter(proposal.reference.u_solution, self.options.chatter_angle_deg)
        if chatter:
            proposal.record.extra["bank_chatter_nodes"] = chatter
        comparable = not self.correcting or iteration > self.corrected_from
        self.settled = self.settled + 1 if comparable and self.stationary() else 0
        small = (
            bool(np.all(self.change < self.tol))
            and iteration > self.regrid_done
            and not chatter
            and self.trust.relaxed
            and self.settled >= SETTLED_ITERATIONS
        )
        step = ((proposal.reference.x - reference.x) / self.scale[None, :]).ravel()
        self.trust.after_iteration(iteration, step)
        self.regularization.after_iteration(iteration, proposal.reference.u_solution)
        self.tr.set_weights(self.trust.weight, self.regularization.weights)
        verdict: scp.Judgement[EnergyIterate, EnergyDerivatives] = scp.Judgement(
            accepted=True, small=small, virtual_control=self.virtual
        )
        ref = proposal.reference
        if self.options.defect_correction and not self.correcting and self.near(small):
            # the plain trapezoid is (nearly) converged: from here on its error is corrected
            self.correcting = True
            self.corrected_from = iteration + 1
            verdict.small = small = False
            proposal.record.extra["defect_correction"] = True
        if small and (proposal.record.relaxation_gap or 0.0) > GAP_TOL:
            # converged inside the disc: the relaxation is not exact, so the lift it flies is
            # not the vehicle's; continue from the bank that flies the same vertical lift
            verdict.small = small = False
            verdict.reference = replace(ref, u=lift_preserving(ref.u_solution, ref.u))
            proposal.record.extra["lift_preserving_projection"] = True
        done = small and self.virtual <= scp.VIRTUAL_CONTROL_TOL
        if not done and self.options.grid != "uniform" and self.regrid_due(iteration, proposal):
            verdict.reference = self.regrid(verdict.reference or proposal.reference)
            self.regrid_done = iteration + 1
            proposal.record.extra["regrid"] = True
        return verdict

    def reject(
        self, proposal: scp.Proposal[EnergyIterate]
    ) -> scp.Judgement[EnergyIterate, EnergyDerivatives]:
        """Keep the reference and solve again under the trust weight ``trust.rejected`` made
        heavier; the step's costs are forgotten."""
        self.values = self.previous_values  # the reference's, as before the step
        self.tr.set_weights(self.trust.weight, self.regularization.weights)
        proposal.record.extra["rejected"] = True
        return scp.Judgement(
            accepted=False, virtual_control=self.virtual, linearization=self.reference_ed
        )

    def near(self, small: bool) -> bool:
        """When the deferred correction starts: on an iterate the plain trapezoid calls
        converged, or earlier once the trust weight is relaxed and every state moved less than
        ``NEAR_FACTOR`` times its tolerance (the correction is small there; from a far iterate
        it is not, and the exact interval maps of a wild reference mislead the step)."""
        return small or (self.trust.relaxed and bool(np.all(self.change < NEAR_FACTOR * self.tol)))

    def stationary(self) -> bool:
        """Every running cost changed by less than ``stop_tolerance.relative_cost`` of its
        value over the last iteration (terminal costs are states: the state test covers
        them)."""
        tol = self.options.stop_tolerance.relative_cost
        for name, value in self.values.items():
            if name not in RUNNING_COSTS:
                continue
            before = self.previous_values.get(name)
            if before is None or abs(value - before) > tol * max(abs(value), abs(before)):
                return False
        return True

    def trajectory(self, reference: EnergyIterate) -> OptimizedTrajectory:
        """The solution's nodes as a time-form trajectory: V from (r, e), time by the
        trapezoid of dt/de, or integrated over each interval once the deferred correction is
        on (as its states are)."""
        p = self.problem
        e, x, u = reference.e_solution, reference.x_solution, reference.u_solution
        ed = energy_dynamics(x, u, e, p.forces, p.omega)
        y, _ = time_state_from_energy(x, e)
        dt_de = 1.0 / ed.edot
        if self.correcting:  # each interval's flight time integrated as its states are
            dt = exact_increments(
                e,
                x,
                u,
                lambda xs, us, es: energy_rates(xs, us, es, p.forces, p.omega),
                lambda xs, r: (1.0 / r.edot)[:, None],
                DEFECT_SUBSTEPS,
            ).running[:, 0]
        else:
            dt = 0.5 * (dt_de[1:] + dt_de[:-1]) * np.diff(e)
        t = np.concatenate([[0.0], np.cumsum(dt)])
        bank = np.arctan2(u[:, 1], u[:, 0])
        return OptimizedTrajectory("energy", e, y, t, bank)

    def objective_terms(self, outcome: scp.ScpOutcome[EnergyIterate]) -> dict[str, float]:
        """The terms as the last iteration recorded them."""
        if not outcome.history:
            return {}
        last = outcome.history[-1].cost_terms
        return {k.split(":", 1)[1]: v for k, v in last.items() if k.startswith("objective:")}

    def regrid_due(self, iteration: int, proposal: scp.Proposal[EnergyIterate]) -> bool:
        """Re-space at ``REGRID_AFTER``, and again whenever a node of the iterate's time-even
        grid lies more than ``REGRID_SHIFT`` intervals from the current one (the flight time
        has moved since: a terminal maneuver left on a coarse interval)."""
        if iteration == REGRID_AFTER:
            return True
        if iteration < REGRID_AFTER or iteration <= self.regrid_done:
            return False
        p, ref = self.problem, proposal.reference
        dt_de = 1.0 / energy_rates(ref.x, ref.u, ref.e, p.forces, p.omega).edot
        shift = np.abs(time_uniform_grid(ref.e, dt_de) - ref.e)
        return bool(np.max(shift) > REGRID_SHIFT * np.mean(np.diff(ref.e)))

    def regrid(self, ref: EnergyIterate) -> EnergyIterate:
        """``ref`` interpolated onto a grid even in its flight time (the solution keeps its own
        grid); the transcription, objective and radius bounds follow the new grid."""
        p, e = self.problem, ref.e
        e_new = time_uniform_grid(e, 1.0 / energy_rates(ref.x, ref.u, e, p.forces, p.omega).edot)
        x = np.column_stack([np.interp(e_new, e, ref.x[:, j]) for j in range(ref.x.shape[1])])
        u = np.column_stack([np.interp(e_new, e, ref.u[:, j]) for j in range(ref.u.shape[1])])
        self.e = e_new
        self.tr.set_grid(e_new)
        self.objective.e = e_new
        if self.r_lower is not None:
            self.r_lower, _ = radius_lower_bound(p.forces, p.limits, e_new, 1.0, self.r_ceiling)
        return EnergyIterate(e_new, x, u, ref.e_solution, ref.x_solution, ref.u_solution)


def run(
    problem: EntryProblem, options: EnergyScpOptions, **hooks: Unpack[RunHooks]
) -> MethodResult:
    """Run paper 000's SCP on ``problem`` with its ``options``."""
    return run_method(lambda: EnergyScp(problem, options), options, hooks)
