"""The verification's compiled right-hand side (``models.flown_rates``) against its Python form,
and the propagation restarted at the nodes against one without compiled rates.

Both forms are the same equations (``models.eom``) and the same bank profile
(``trajectory.bank_profile``), so they agree to round-off: 1e-12 relative on the rates.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tests.variants.cases import variants
from worker.solver import verification
from worker.solver.models import flown_rates
from worker.solver.models.bank_state_compiled import compiled_parameters, float_arrays
from worker.solver.models.scalar_rates import time_rates
from worker.solver.problem import EntryProblem, build_problem
from worker.solver.trajectory import OptimizedTrajectory, bank_profile
from worker.solver.verification import propagate

RNG = np.random.default_rng(11)


def _problem(variant: str) -> EntryProblem:
    return build_problem({v.name: v for v in variants()}[variant].document())


def _traj(kind: int, problem: EntryProblem) -> OptimizedTrajectory:
    """A made-up trajectory of 30 nodes with the bank profile of ``kind``."""
    t = np.linspace(0.0, 1600.0, 30) / problem.scales.time_s
    bank = np.radians(RNG.uniform(-70.0, 70.0, 30))
    rate = RNG.uniform(-0.5, 0.5, 30)
    if kind == flown_rates.LINEAR_IN_ENERGY:
        grid = np.linspace(-0.95, -0.49, 30)
        return OptimizedTrajectory("energy", grid, np.zeros((30, 6)), t, bank)
    hold = rate if kind == flown_rates.HOLD_IN_TIME else None
    return OptimizedTrajectory("time", t, np.zeros((30, 6)), t, bank, bank_rate=hold)


@pytest.mark.parametrize(
    "kind",
    [flown_rates.LINEAR_IN_TIME, flown_rates.HOLD_IN_TIME, flown_rates.LINEAR_IN_ENERGY],
)
def test_compiled_rates_are_the_python_ones(kind: int) -> None:
    problem = _problem("foh-nodes-40")
    params = compiled_parameters(problem.forces, problem.omega)
    assert params is not None
    traj = _traj(kind, problem)
    rate = traj.bank_rate if traj.bank_rate is not None else traj.bank
    g, b, w = float_arrays(traj.grid, traj.bank, rate)
    for _ in range(200):
        y = np.array(
            [1.0 + RNG.uniform(0.002, 0.015), 0.3, RNG.uniform(-1, 1), RNG.uniform(0.2, 0.95),
             RNG.uniform(-0.1, 0.05), RNG.uniform(-1, 2)]
        )  # fmt: skip
        t = RNG.uniform(traj.t[0], traj.t[-1])
        s = 1.0 / y[0] - 0.5 * y[3] ** 2 if traj.grid_kind == "energy" else t
        sigma = bank_profile(traj, s)
        _, lift, drag, _ = problem.forces.lift_drag(y[0], y[3])
        expected = time_rates(
            y, math.cos(sigma), math.sin(sigma), float(lift), float(drag), problem.omega
        )
        got = flown_rates.flown_rates(t, y, kind, g, b, w, params)
        assert np.allclose(got, expected, rtol=1e-12, atol=1e-15), (kind, got - expected)


@pytest.mark.slow
def test_the_restarted_compiled_propagation_is_the_python_one(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Case 1's optimized controls propagated with the compiled rates and with the Python rates
    (both restarted at the nodes, DOP853 at rtol 1e-10), and in one integration without
    restarts at rtol 1e-13 (the reference: tight enough that its own error at the bank's kinks,
    which it steps over, stays below 1e-10): the end states agree to 1e-9 of the nondimensional
    states (6 mm, 8e-6 m/s), far below what the checks allow (500 m, 10 m/s). At the
    verification's own rtol the unrestarted integration is off by 7e-9 to 1.5e-8 at the kinks,
    depending on the controls; the restarted one by 1.2e-10."""
    from worker.solver.methods.foh_ptr.method import run

    problem = _problem("foh-nodes-40")
    doc = {v.name: v for v in variants()}["foh-nodes-40"].document()
    traj = run(problem, doc.method).trajectory  # type: ignore[arg-type]
    assert traj is not None
    fast = propagate(problem, traj)
    whole = solve_ivp(  # one integration over the whole flight, no restarts, tight
        verification._rhs(problem, traj, lambda: None),
        (0.0, float(traj.t[-1])),
        problem.y0,
        method="DOP853",
        rtol=1e-13,
        atol=1e-15,
    )
    assert np.max(np.abs(fast.y[:, -1] - whole.y[:, -1])) < 1e-9
    monkeypatch.setattr(verification, "compiled_parameters", lambda forces, omega: None)
    slow = propagate(problem, traj)
    assert fast.status == slow.status == 0
    assert np.max(np.abs(fast.y[:, -1] - slow.y[:, -1])) < 1e-8
    probe = np.linspace(0.0, traj.t[-1], 333)
    assert np.max(np.abs(fast.sol(probe) - slow.sol(probe))) < 1e-8
