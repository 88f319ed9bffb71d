"""SQP on the collocation NLP (paper 004 sec. 2.1, after Gill & Wong 2012): one convex QP per
iteration (Clarabel), elastic in its constraint rows (the Sl1QP of Fletcher, Practical Methods
of Optimization, sec. 12.4: a linearization that cannot be met is met as well as it can, and
the slacks say which row could not), a trust box on the scaled step, and a line search on the
l1 exact penalty (or paper 003's non-monotone filter, ``scp.filter``).

Stops: converged (violation and step under their tolerances), infeasible (the penalty at its
ceiling and the steps stalled with conditions unmet: which ones, by how much), or a budget.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from worker.solver.conic import ConicBackend
from worker.solver.conic.problem import ConeProblem, ConeSpec
from worker.solver.conic.status import ConicStatus
from worker.solver.methods.lgl_sqp.nlp import DYNAMICS_WEIGHT, Evaluation, PhasedNlp
from worker.solver.scp.filter import NonMonotoneFilter
from worker.solver.solve_clock import SolveClock

Array = np.ndarray

PENALTY_START = 1.0e2
PENALTY_MAX = 1.0e8
RESTORED_VIOLATION = 1e-4
"""Largest scaled violation at which the restoration stage (the conditions alone, objective
off) hands over to the optimization."""
SLACK_ACTIVE = 1e-9
"""An elastic slack above this (scaled) means the QP relaxed its row."""
STEERING_SHARE = 0.9
"""The share of the violation a step's linear model may keep before the penalty rises."""
TRUST_START = 4.0
TRUST_MIN = 1e-6
TRUST_MAX = 100.0
ARMIJO = 1e-4
STEP_MIN = 1.0 / 64.0
SETTLE_ITERATIONS = 3
SETTLE_RELATIVE = 1e-8
"""A feasible run whose objective moved by less than this share over the last
SETTLE_ITERATIONS iterations has converged (the tail of a step that shrinks geometrically
changes nothing the answer reports)."""
SETTLED_VIOLATION = 1e-6
"""Largest scaled violation of a run whose objective has settled and whose full steps are its
own (not the trust box's): such a run has converged even above ``feasibility_tolerance``. A
flat direction of the NLP (a control the objective and the limits barely feel) and the
convexified Hessian leave full steps that shrink by a fraction of a percent per iteration, each
leaving second-order defects of about its square; 1e-6 of the state scales is 0.13 m of
altitude and 1.6 mm/s of speed, far below what the verification resolves."""
MERIT_MEMORY = 4
"""Accepted points the non-monotone merit test looks back over (a full step that raises the
merit for a while, the Maratos effect near a solution, is still taken)."""
PROXIMAL = 1e-7
"""Proximal weight added to the QP's Hessian (scaled units): a unique step when the
convexified Hessian is singular (the durations, a linear objective)."""


@dataclass
class SqpIteration:
    """What one iteration did, for the history."""

    iteration: int
    objective: float
    merit: float
    violation_dynamics: float
    violation_conditions: float
    max_violation: float
    step: float  # largest scaled step component of the QP
    squared_step: float  # the QP step's squared length (scaled units)
    largest_defect: float  # the largest dynamics row at the iteration's point (scaled units)
    step_length: float
    penalty: float
    trust: float
    qp_status: str
    qp_solve_s: float
    qp_setup_s: float
    qp_iterations: int
    elastic: float
    accepted: bool
    z: Array
    wall_s: float
    line_search: str
    largest_step_at: str = ""


@dataclass
class SqpOutcome:
    """How the SQP ended, its last point and evaluation, and the iterations."""

    status: str  # converged | infeasible | max_iterations | timed_out | cancelled | failed
    z: Array
    evaluation: Evaluation
    iterations: list[SqpIteration] = field(default_factory=list)
    message: str | None = None
    qp_solve_s: float = 0.0


@dataclass
class SqpSettings:
    max_iterations: int
    time_limit_s: float
    feasibility_tolerance: float
    step_tolerance: float
    line_search: str = "merit"
    conic_time_limit_s: float | None = None


def _row_weights(nlp: PhasedNlp) -> Array:
    """Elastic weight of each equality row: the dynamics rows heavier than the end rows."""
    return np.array([1.0 if k == "end" else DYNAMICS_WEIGHT for k in nlp.eq_info.kind])


def _merit(nlp: PhasedNlp, ev: Evaluation, rho: float, weights: Array, share: float = 1.0) -> float:
    return share * ev.objective + rho * (
        float(weights @ np.abs(ev.eq)) + float(np.maximum(ev.ineq, 0.0).sum())
    )


def _build_qp(
    nlp: PhasedNlp, z: Array, ev: Evaluation, H: sp.csc_matrix, rho: float, trust: float,
    weights: Array, share: float = 1.0,
) -> tuple[ConeProblem, int, int]:  # fmt: skip
    """The elastic QP in x = [d, p, n, t]: returns the problem and the counts (m_eq, m_in)."""
    n = nlp.n
    m_eq, m_in = ev.eq.size, ev.ineq.size
    S = nlp.scale
    ub = np.minimum((nlp.upper - z) / S, trust)
    lb = np.maximum((nlp.lower - z) / S, -trust)
    ub = np.maximum(ub, 0.0)  # z lies within its bounds; roundoff must not make it infeasible
    lb = np.minimum(lb, 0.0)
    nvar = n + 2 * m_eq + m_in
    P = sp.block_diag(
        [sp.triu(H + PROXIMAL * sp.identity(n, format="csc")), sp.csc_matrix((nvar - n, nvar - n))],
        format="csc",
    )
    q = np.concatenate([share * ev.gradient, rho * weights, rho * weights, rho * np.ones(m_in)])
    I_eq = sp.identity(m_eq, format="csc")
    I_in = sp.identity(m_in, format="csc")
    Z = sp.csc_matrix
    rows_eq = sp.hstack([ev.jac_eq, -I_eq, I_eq, Z((m_eq, m_in))])
    rows_in = sp.hstack([ev.jac_ineq, Z((m_in, 2 * m_eq)), -I_in])
    I_n = sp.identity(n, format="csc")
    box = sp.vstack([sp.hstack([I_n, Z((n, nvar - n))]), sp.hstack([-I_n, Z((n, nvar - n))])])
    slack_rows = sp.hstack([Z((nvar - n, n)), -sp.identity(nvar - n)])
    A = sp.vstack([rows_eq, rows_in, box, slack_rows], format="csc")
    b = np.concatenate([-ev.eq, -ev.ineq, ub, -lb, np.zeros(nvar - n)])
    cones = ConeSpec(n_zero=m_eq, n_nonneg=m_in + 2 * n + nvar - n)
    return ConeProblem(P=P, q=q, A=A, b=b, cones=cones), m_eq, m_in


def _corrected(nlp: PhasedNlp, zt: Array, ev: Evaluation) -> tuple[Array, Evaluation | None]:
    """zt moved by the least-norm scaled step d with J_eq d = -c_eq(zt) (J at zt), within the
    bounds, and its evaluation; None when the correction cannot be computed."""
    J = ev.jac_eq.tocsc()
    try:
        w = spla.spsolve((J @ J.T).tocsc(), -ev.eq)
    except (RuntimeError, ValueError):
        return zt, None
    d = J.T @ w
    if not np.all(np.isfinite(d)):
        return zt, None
    zc = np.clip(zt + nlp.scale * d, nlp.lower, nlp.upper)
    return zc, nlp.evaluate(zc)


def solve_sqp(
    nlp: PhasedNlp,
    z0: Array,
    settings: SqpSettings,
    backend: ConicBackend,
    *,
    on_iteration: Callable[[SqpIteration, Evaluation], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
    clock: SolveClock | None = None,
    offset: int = 0,
) -> SqpOutcome:
    """Run the SQP from ``z0`` (clipped into the bounds); ``clock``: the time limit's clock
    (default: ``settings.time_limit_s`` CPU seconds from now); ``offset``: records of the
    history before this SQP, by which the iterations its messages name are shifted into the
    history's numbering."""
    clock = clock or SolveClock.start(settings.time_limit_s)
    z = np.clip(z0, nlp.lower, nlp.upper)
    ev = nlp.evaluate(z)
    weights = _row_weights(nlp)
    lam_eq, lam_in = np.zeros(ev.eq.size), np.zeros(ev.ineq.size)
    rho, trust = PENALTY_START, TRUST_START
    filt = NonMonotoneFilter()
    out = SqpOutcome(status="max_iterations", z=z, evaluation=ev)
    stalled = 0
    objectives: list[float] = []  # the objective at each iterate
    last_alpha = 0.0
    restoring = True  # first meet the conditions (objective off), then optimize
    recent: list[float] = []  # merits of the last accepted points (non-monotone reference)
    for it in range(1, settings.max_iterations + 1):
        t_it = time.perf_counter()
        if should_stop is not None and should_stop():
            out.status, out.message = "cancelled", "cancelled by the caller"
            break
        expired = clock.expired()
        if expired is not None:
            out.status = "timed_out"
            out.message = f"{expired} reached after {it - 1} iterations"
            break
        now_max = max(
            float(np.max(np.abs(ev.eq))) if ev.eq.size else 0.0,
            float(np.max(ev.ineq)) if ev.ineq.size else 0.0,
        )
        if restoring and now_max <= RESTORED_VIOLATION:
            restoring = False  # feasible: the objective enters from here on
            recent.clear()
            rho = PENALTY_START  # the restoration's price says nothing of the optimization's
            lam_eq, lam_in = np.zeros_like(lam_eq), np.zeros_like(lam_in)
        share = 0.0 if restoring else 1.0
        if restoring:
            # the multipliers of a relaxed QP are the penalty's prices, and the convexified
            # curvature they weigh makes the step that meets a condition look dearer than its
            # slack: the restoration takes trust-box SLP steps on the rows alone
            H = nlp.hessian(z, ev, np.zeros_like(lam_eq), np.zeros_like(lam_in))
        else:
            H = nlp.hessian(z, ev, lam_eq, lam_in)
        qp, m_eq, m_in = _build_qp(nlp, z, ev, H, rho, trust, weights, share)
        sol = backend.solve(qp, time_limit_s=settings.conic_time_limit_s)
        out.qp_solve_s += sol.solve_time_s
        usable = sol.x is not None and sol.status in (ConicStatus.OPTIMAL, ConicStatus.INACCURATE)
        if not usable or sol.x is None:
            trust *= 0.25
            if trust < TRUST_MIN:
                out.status = "failed"
                out.message = f"the QP failed at iteration {offset + it} ({sol.raw_status})"
                break
            continue
        x = sol.x
        d = x[: nlp.n]
        pe, ne = x[nlp.n : nlp.n + m_eq], x[nlp.n + m_eq : nlp.n + 2 * m_eq]
        te = x[nlp.n + 2 * m_eq :]
        elastic = float(weights @ (pe + ne) + te.sum())
        if sol.y is not None:
            y_eq, y_in = sol.y[:m_eq].copy(), sol.y[m_eq : m_eq + m_in].copy()
            # a row the QP relaxed has its multiplier at the penalty, the price of its slack, not
            # an estimate of the NLP's: kept out of the Hessian, whose steps it would stiffen
            y_eq[pe + ne > SLACK_ACTIVE] = 0.0
            y_in[te > SLACK_ACTIVE] = 0.0
        else:
            y_eq, y_in = lam_eq, lam_in
        step = float(np.max(np.abs(d))) if d.size else 0.0
        viol_dyn, viol_cond = nlp.violation(ev)
        max_viol = now_max
        phi0 = _merit(nlp, ev, rho, weights, share)
        objectives.append(ev.objective)
        settled = len(objectives) > SETTLE_ITERATIONS and max(
            abs(a - ev.objective) for a in objectives[-SETTLE_ITERATIONS - 1 :]
        ) <= SETTLE_RELATIVE * max(1.0, abs(ev.objective))
        free_step = step < 0.5 * trust  # the QP's step is its own, not the trust box's
        settled_here = settled and free_step and last_alpha == 1.0
        converged = not restoring and (
            (
                max_viol <= settings.feasibility_tolerance
                and (step <= settings.step_tolerance or settled_here)
            )
            or (settled_here and max_viol <= max(SETTLED_VIOLATION, settings.feasibility_tolerance))
        )
        if converged:
            lam_eq, lam_in = y_eq, y_in
            out.iterations.append(
                _record(it, ev, phi0, (viol_dyn, viol_cond, max_viol), step, 0.0, rho, trust, sol,
                        elastic, True, z, t_it, settings.line_search,
                        (float(d @ d), nlp.largest_defect(ev)))
            )  # fmt: skip
            if on_iteration is not None:
                on_iteration(out.iterations[-1], ev)
            out.status = "converged"
            break
        # directional derivative of the merit along d (the linear model's decrease)
        lin_eq = ev.eq + ev.jac_eq @ d
        lin_in = ev.ineq + ev.jac_ineq @ d
        model_viol = float(weights @ np.abs(lin_eq)) + float(np.maximum(lin_in, 0.0).sum())
        now_viol = float(weights @ np.abs(ev.eq)) + float(np.maximum(ev.ineq, 0.0).sum())
        slope = share * float(ev.gradient @ d) + rho * (model_viol - now_viol)
        if settings.line_search == "filter" and not filt.history:
            filt.start(now_viol, ev.objective)
        alpha = 1.0
        accepted = False
        trial_ev = ev
        while alpha >= STEP_MIN:
            zt = np.clip(z + alpha * nlp.scale * d, nlp.lower, nlp.upper)
            trial_ev = nlp.evaluate(zt)
            if settings.line_search == "filter":
                tv = float(weights @ np.abs(trial_ev.eq)) + float(
                    np.maximum(trial_ev.ineq, 0.0).sum()
                )
                ok = filt.acceptable(tv, trial_ev.objective)
                if ok:
                    filt.accept(tv, trial_ev.objective)
            else:  # non-monotone Armijo: against the largest of the last few merits
                phi = _merit(nlp, trial_ev, rho, weights, share)
                ref = max([phi0, *recent[-MERIT_MEMORY:]])
                ok = bool(np.isfinite(phi)) and phi <= ref + ARMIJO * alpha * min(slope, 0.0)
            if ok:
                accepted = True
                break
            if alpha == 1.0 and settings.line_search == "merit":
                # second-order correction (Nocedal & Wright, Numerical Optimization, sec. 18.3):
                # the full step's new equality residuals taken back by a least-norm step, so
                # the constraints' curvature does not cut a good step (the Maratos effect)
                zc, corrected = _corrected(nlp, zt, trial_ev)
                if corrected is not None:
                    phi = _merit(nlp, corrected, rho, weights, share)
                    ref = max([phi0, *recent[-MERIT_MEMORY:]])
                    if np.isfinite(phi) and phi <= ref + ARMIJO * min(slope, 0.0):
                        zt, trial_ev, accepted = zc, corrected, True
                        break
            alpha *= 0.5
        last_alpha = alpha if accepted else 0.0
        if accepted:
            recent.append(phi0)
            z, ev = zt, trial_ev
            lam_eq = lam_eq + alpha * (y_eq - lam_eq)
            lam_in = lam_in + alpha * (y_in - lam_in)
            if alpha == 1.0 and step >= 0.9 * trust:
                trust = min(2.0 * trust, TRUST_MAX)
            elif alpha < 0.5:  # the model held over a small share of the step: box it there
                trust = max(min(trust, 2.0 * alpha * step), TRUST_MIN)
        else:
            trust = max(0.25 * min(trust, step), TRUST_MIN)
        # penalty: raise it while the QP pays slack at its current price
        # steering (after Byrd, Nocedal & Waltz 2008): raise the penalty when the step, at the
        # current price, does not reduce the linearized violation by a tenth of it
        stuck = model_viol > STEERING_SHARE * now_viol and now_viol > settings.feasibility_tolerance
        if elastic > settings.feasibility_tolerance and rho < PENALTY_MAX and stuck:
            rho = min(10.0 * rho, PENALTY_MAX)
            recent.clear()  # merits at another price do not compare
        now = (*nlp.violation(ev), max_viol)
        largest = nlp.describe_variable(int(np.argmax(np.abs(d)))) if d.size else ""
        out.iterations.append(
            _record(it, ev, _merit(nlp, ev, rho, weights), now, step, alpha if accepted else 0.0,
                    rho, trust, sol, elastic, accepted, z, t_it, settings.line_search,
                    (float(d @ d), nlp.largest_defect(ev)))
        )  # fmt: skip
        out.iterations[-1].largest_step_at = largest
        if on_iteration is not None:
            on_iteration(out.iterations[-1], ev)
        small = step <= 10.0 * settings.step_tolerance or trust <= 10.0 * TRUST_MIN
        stalled = stalled + 1 if small and max_viol > settings.feasibility_tolerance else 0
        if stalled >= 3 and rho >= PENALTY_MAX:
            out.status = "infeasible"
            out.message = f"the steps stalled at iteration {offset + it} with conditions unmet"
            break
    out.z, out.evaluation = z, ev
    return out


def _record(
    it: int, ev: Evaluation, merit: float, violations: tuple[float, float, float], step: float,
    alpha: float, rho: float, trust: float, sol: Any, elastic: float, accepted: bool, z: Array,
    t_it: float, line_search: str, sizes: tuple[float, float],
) -> SqpIteration:  # fmt: skip
    """The iteration's record; ``sizes``: the QP step's squared length and the largest dynamics
    row at the point the iteration ends on."""
    viol_dyn, viol_cond, max_viol = violations
    return SqpIteration(
        iteration=it,
        objective=ev.objective,
        merit=merit,
        violation_dynamics=viol_dyn,
        violation_conditions=viol_cond,
        max_violation=max_viol,
        step=step,
        squared_step=sizes[0],
        largest_defect=sizes[1],
        step_length=alpha,
        penalty=rho,
        trust=trust,
        qp_status=sol.status.value,
        qp_solve_s=sol.solve_time_s,
        qp_setup_s=sol.setup_time_s,
        qp_iterations=sol.iterations,
        elastic=elastic,
        accepted=accepted,
        z=z.copy(),
        wall_s=time.perf_counter() - t_it,
        line_search=line_search,
    )
