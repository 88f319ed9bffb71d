"""A new method on the shared SCP driver without editing it: the 8-state model (angle of attack
and bank as states, their rates as controls) steered by a small trapezoidal SCP written here.

The method drives the bank and the angle of attack of the X-33-like vehicle (built-in scenario
``rlv-max-terminal-velocity``) from their initial values to new ones in 100 s at the least
control effort, while the point-mass states follow the nonlinear dynamics. It supplies the
driver's hooks only (``ScpMethod``: start, linearize, subproblem, solve, propose, judge) and
uses ``StateLayout`` for its scales and tolerances, so it shows that a method with another state
vector needs no change to ``scp.loop``, ``models.layout`` or any other method.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
import scipy.sparse as sp

from app.schemas import ProblemDocument
from worker.solver.conic import ConeProblem, ConeSpec, ConicSolution, make_backend
from worker.solver.models.alpha_bank_state import (
    ALPHA,
    SIGMA,
    AlphaBankStateDerivatives,
    alpha_bank_state_dynamics,
)
from worker.solver.models.layout import ALPHA_BANK_STATE
from worker.solver.problem import EntryProblem, build_problem
from worker.solver.scenarios import get_scenario
from worker.solver.scp.history import IterationRecord, solver_fields
from worker.solver.scp.loop import Budget, ConicCall, Judgement, Proposal, run_scp

Array = np.ndarray
K = 21  # nodes over 100 s: intervals of 5 s
FLIGHT_S = 100.0
BANK_END_DEG, ALPHA_DROP_DEG = 30.0, 5.0
RATE_MAX_DEG_S = 2.0
TRUST_WEIGHT = 1e-6  # light: the steering is nearly linear, so near-Newton steps are safe
STOP = {name: 1e-3 for name in ALPHA_BANK_STATE.names}  # m, deg, m/s: a converged step


@dataclass
class Iterate:
    z: Array  # (K, 8)
    w: Array  # (K, 2): bank rate, alpha rate


class SteerAlphaBank:
    """Minimum-effort steering of (sigma, alpha) with trapezoidal dynamics rows (8 states)."""

    def __init__(self, problem: EntryProblem) -> None:
        self.problem = problem
        sc = problem.scales
        self.h = FLIGHT_S / (K - 1) / sc.time_s
        self.unit_z = ALPHA_BANK_STATE.trust_units(sc)
        self.unit_w = math.radians(1.0) * sc.time_s * np.ones(2)  # 1 deg/s
        self.rate_max = math.radians(RATE_MAX_DEG_S) * sc.time_s
        self.tol = ALPHA_BANK_STATE.deltas_from_si(STOP, sc)
        self.nz, self.nu = ALPHA_BANK_STATE.size, 2
        self.n = K * (self.nz + self.nu)

    def f(self, it: Iterate, jacobians: bool = True) -> AlphaBankStateDerivatives:
        return alpha_bank_state_dynamics(
            it.z, it.w, self.problem.forces, self.problem.omega, jacobians=jacobians
        )

    def start(self) -> Iterate:
        """Constant bank and angle of attack, propagated by RK4 (4 steps per interval)."""
        p = self.problem
        assert p.forces.alpha_schedule is not None
        alpha0 = math.radians(float(p.forces.alpha_schedule.alpha_deg(np.array([7450.0]))[0][0]))
        z = np.zeros((K, self.nz))
        z[0, :6] = p.y0
        z[0, SIGMA], z[0, ALPHA] = 0.0, alpha0
        w = np.zeros((1, 2))
        for k in range(K - 1):
            x = z[k : k + 1].copy()
            dt = self.h / 4
            for _ in range(4):
                k1 = self.f(Iterate(x, w), False).F
                k2 = self.f(Iterate(x + 0.5 * dt * k1, w), False).F
                k3 = self.f(Iterate(x + 0.5 * dt * k2, w), False).F
                k4 = self.f(Iterate(x + dt * k3, w), False).F
                x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            z[k + 1] = x[0]
        self.targets = {
            SIGMA: math.radians(BANK_END_DEG),
            ALPHA: alpha0 - math.radians(ALPHA_DROP_DEG),
        }
        return Iterate(z, np.zeros((K, 2)))

    def linearize(self, ref: Iterate) -> AlphaBankStateDerivatives:
        return self.f(ref)

    def _col_z(self, k: int, i: int) -> int:
        return k * self.nz + i

    def _col_w(self, k: int, j: int) -> int:
        return K * self.nz + k * self.nu + j

    def subproblem(
        self, ref: Iterate, lin: AlphaBankStateDerivatives, iteration: int
    ) -> ConeProblem:
        """Variables: scaled changes of the nodes and the rates. Rows: fixed initial node,
        trapezoidal dynamics, terminal bank and alpha (zero cone), rate bounds (nonnegative).
        Cost: the rates' squares plus a light trust-region penalty on every scaled change."""
        nz, nu, h = self.nz, self.nu, self.h
        rows: list[tuple[int, int, float]] = []
        b_eq: list[float] = []

        def row(entries: list[tuple[int, float]], rhs: float) -> None:
            r = len(b_eq)
            rows.extend((r, c, v) for c, v in entries)
            b_eq.append(rhs)

        for i in range(nz):
            row([(self._col_z(0, i), 1.0)], 0.0)
        F, A, B = lin.F, lin.A, lin.B
        assert A is not None and B is not None
        for k in range(K - 1):
            defect = ref.z[k + 1] - ref.z[k] - 0.5 * h * (F[k] + F[k + 1])
            for i in range(nz):
                entries: list[tuple[int, float]] = []
                for j in range(nz):
                    a = -0.5 * h * A[k + 1, i, j] + (1.0 if i == j else 0.0)
                    c = -0.5 * h * A[k, i, j] - (1.0 if i == j else 0.0)
                    entries.append((self._col_z(k + 1, j), a * self.unit_z[j] / self.unit_z[i]))
                    entries.append((self._col_z(k, j), c * self.unit_z[j] / self.unit_z[i]))
                for j in range(nu):
                    scale = self.unit_w[j] / self.unit_z[i]
                    entries.append((self._col_w(k, j), -0.5 * h * B[k, i, j] * scale))
                    entries.append((self._col_w(k + 1, j), -0.5 * h * B[k + 1, i, j] * scale))
                row([(c, v) for c, v in entries if v != 0.0], -defect[i] / self.unit_z[i])
        for i, target in self.targets.items():
            row([(self._col_z(K - 1, i), 1.0)], (target - ref.z[-1, i]) / self.unit_z[i])
        n_eq = len(b_eq)
        b = list(b_eq)
        for k in range(K):
            for j in range(nu):
                for sign in (1.0, -1.0):  # sign * (w + unit dw) <= rate_max
                    rows.append((len(b), self._col_w(k, j), sign * self.unit_w[j]))
                    b.append(self.rate_max - sign * ref.w[k, j])
        r, c, v = zip(*rows, strict=True)
        A_mat = sp.csc_matrix((v, (r, c)), shape=(len(b), self.n))
        diag = np.full(self.n, TRUST_WEIGHT)  # the trust region, per scaled variable
        q = np.zeros(self.n)
        for k in range(K):
            for j in range(nu):
                col = self._col_w(k, j)
                diag[col] += 2.0 * self.unit_w[j] ** 2 / self.rate_max**2
                q[col] = 2.0 * ref.w[k, j] * self.unit_w[j] / self.rate_max**2
        P = sp.diags(diag, format="csc")
        return ConeProblem(P, q, A_mat, np.array(b), ConeSpec(n_eq, len(b) - n_eq))

    def solve(
        self, problem: ConeProblem, conic: ConicCall, limit_s: float, deadline: float
    ) -> ConicSolution:
        return conic(problem, limit_s)

    def propose(
        self, ref: Iterate, lin: AlphaBankStateDerivatives, solution: ConicSolution, iteration: int
    ) -> Proposal[Iterate]:
        x = solution.x
        assert x is not None
        dz = x[: K * self.nz].reshape(K, self.nz) * self.unit_z
        dw = x[K * self.nz :].reshape(K, self.nu) * self.unit_w
        self.change = np.max(np.abs(dz), axis=0)
        record = IterationRecord(
            iteration=iteration,
            cost=float(np.sum((ref.w + dw) ** 2)),
            cost_terms={},
            objective_value=None,
            max_state_change=ALPHA_BANK_STATE.deltas_to_si(self.change, self.problem.scales),
            trust_region_slack=float(np.sum(x**2)),
            virtual_control_norm=0.0,
            linearization_error=0.0,
            nodes_post_corrected=0,
            relaxation_gap=0.0,
            **solver_fields(solution),
        )
        return Proposal(Iterate(ref.z + dz, ref.w + dw), record)

    def judge(
        self, ref: Iterate, proposal: Proposal[Iterate]
    ) -> Judgement[Iterate, AlphaBankStateDerivatives]:
        return Judgement(accepted=True, small=bool(np.all(self.change <= self.tol)))


@pytest.fixture(scope="module")
def problem() -> EntryProblem:
    return build_problem(
        ProblemDocument.model_validate(get_scenario("rlv-max-terminal-velocity").problem)
    )


@pytest.mark.slow
def test_an_eight_state_method_runs_on_the_unchanged_driver(problem: EntryProblem) -> None:
    """Converges, meets the terminal bank and alpha, keeps the rate bounds, and its nodes solve
    the nonlinear trapezoidal equations.

    Tolerances: the terminal rows are linear in the states, so they hold to the conic solver's
    feasibility (1e-8 relative; 1e-7 rad is ample). The nonlinear trapezoid defect of the last
    iterate is bounded by the last step (converged: every state moved < 1e-3 m, deg, m/s), whose
    square is what the linearization misses: 1e-6 trust units is two orders above that.
    """
    method = SteerAlphaBank(problem)
    history: list[IterationRecord] = []
    out = run_scp(method, Budget(20, 60.0), make_backend("clarabel"), on_iteration=history.append)
    assert out.status == "converged", out.failure_message
    assert 2 <= len(out.history) < 20 and history == out.history
    ref = out.reference
    assert ref is not None
    for i, target in method.targets.items():
        assert abs(ref.z[-1, i] - target) < 1e-7
    assert np.max(np.abs(ref.w)) <= method.rate_max * (1 + 1e-7)
    F = method.f(ref, False).F
    defect = ref.z[1:] - ref.z[:-1] - 0.5 * method.h * (F[1:] + F[:-1])
    assert np.max(np.abs(defect) / method.unit_z) < 1e-6
    # the alpha change moved the point-mass states: the model is coupled, not two integrators
    assert np.max(np.abs(ref.z[:, 3] - method_start(problem).z[:, 3])) > 1e-4


def method_start(problem: EntryProblem) -> Iterate:
    """The method's initial reference, for comparison."""
    return SteerAlphaBank(problem).start()
