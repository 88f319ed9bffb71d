"""The flown bank between the nodes: foh-ptr's turning-point rows (``foh_rows.bank_vertex``) and
the verification's control-limit check (``verification._control_peaks``).

Under a first-order-hold bank rate the bank is quadratic in time over each interval, so a rate
that reverses inside a long interval turns the bank beyond the values at its nodes: paper 002
case 1 at 40 nodes flew 180 deg between nodes held at 80 deg until both were added.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.variants.cases import variants
from worker.solver.problem import EntryProblem, build_problem
from worker.solver.trajectory import OptimizedTrajectory, bank_profile, bank_profile_at
from worker.solver.transcription.foh_rows import bank_vertex
from worker.solver.verification import VerificationTolerances, _control_peaks

RNG = np.random.default_rng(7)


def _dense_bank(z_bank: np.ndarray, w: np.ndarray, s: np.ndarray, k: int) -> np.ndarray:
    tau = np.linspace(0.0, 1.0, 100_001)
    return z_bank[k] + s[k] * (w[k] * tau + 0.5 * (w[k + 1] - w[k]) * tau * tau)


def test_the_turning_point_is_the_extremum_of_each_interval() -> None:
    """Where the rate changes sign, sigma(tau*) is the interval's extreme bank (a dense grid of
    1e5 steps finds it to 1e-9 of the scale); where it keeps its sign, the bank is monotone and
    sigma(1/2) lies between the node values."""
    z_bank = RNG.uniform(-1.0, 1.0, 30)
    w = RNG.uniform(-2.0, 2.0, 30)
    s = RNG.uniform(0.01, 0.1, 29)
    tau, value, _, _ = bank_vertex(z_bank, w, s)
    for k in range(29):
        dense = _dense_bank(z_bank, w, s, k)
        if w[k] * w[k + 1] < 0:
            extreme = dense.max() if w[k] > 0 else dense.min()
            assert value[k] == pytest.approx(extreme, abs=1e-9)
            assert 0.0 < tau[k] < 1.0
        else:
            assert tau[k] == 0.5
            assert min(dense[0], dense[-1]) <= value[k] <= max(dense[0], dense[-1])


def test_the_row_coefficients_are_the_derivatives_at_the_turning_point() -> None:
    """The coefficients in w_k, w_{k+1} and s_k are the exact derivatives of sigma(tau*) at a
    fixed tau* (forward differences of 1e-7 agree to 1e-6): the rows are the linearization of the
    extreme bank (by the envelope theorem its derivative in the variables is that at tau*)."""
    z_bank, w, s = np.array([0.2, 0.1]), np.array([1.5, -0.8]), np.array([0.07])
    tau, value, on_rates, on_length = bank_vertex(z_bank, w, s)

    def at(zb: np.ndarray, wv: np.ndarray, sv: np.ndarray) -> float:
        t = tau[0]
        return float(zb[0] + sv[0] * (wv[0] * (t - t * t / 2) + wv[1] * t * t / 2))

    h = 1e-7
    assert (at(z_bank, w + np.array([h, 0.0]), s) - value[0]) / h == pytest.approx(
        on_rates[0, 0], abs=1e-6
    )
    assert (at(z_bank, w + np.array([0.0, h]), s) - value[0]) / h == pytest.approx(
        on_rates[0, 1], abs=1e-6
    )
    assert (at(z_bank, w, s + h) - value[0]) / h == pytest.approx(on_length[0], abs=1e-6)


def _case_1_problem() -> EntryProblem:
    return build_problem({v.name: v for v in variants()}["foh-nodes-40"].document())


def _traj(
    bank_deg: list[float], rate_deg_s: list[float], t_s: list[float], time_s: float
) -> OptimizedTrajectory:
    t = np.array(t_s) / time_s
    return OptimizedTrajectory(
        "time",
        t,
        np.zeros((t.size, 6)),
        t,
        np.radians(bank_deg),
        bank_rate=np.radians(rate_deg_s) * time_s,
    )


def test_the_verification_sees_a_bank_beyond_its_limit_between_nodes() -> None:
    """Nodes at 60 and 70 deg, 40 s apart, rate +10 then -9.5 deg/s: the bank turns at about
    t = 20.5 s near 60 + 10 * 20.5 / 2 = 162 deg. The check reports that peak (20 samples per
    interval find it within a degree) and fails the limit; a gentle profile passes."""
    problem = _case_1_problem()
    sc = problem.scales
    over = _traj([60.0, 70.0], [10.0, -9.5], [0.0, 40.0], sc.time_s)
    t_fine = np.linspace(0.0, over.t[-1], 21)
    peaks, ok = _control_peaks(problem, over, t_fine, t_fine, VerificationTolerances())
    assert not ok and not peaks["bank_deg"]["within"]
    exact = 60.0 + 10.0 * (10.0 / 19.5 * 40.0) / 2.0
    assert peaks["bank_deg"]["max"] == pytest.approx(exact, abs=1.0)
    assert peaks["bank_rate_deg_s"]["within"]
    gentle = _traj([60.0, 70.0], [0.25, 0.25], [0.0, 40.0], sc.time_s)
    peaks, ok = _control_peaks(problem, gentle, t_fine, t_fine, VerificationTolerances())
    assert ok and peaks["bank_deg"]["max"] == pytest.approx(70.0, abs=1e-9)


def test_vectorized_bank_profile_is_the_scalar_one() -> None:
    problem = _case_1_problem()
    traj = _traj([10.0, -30.0, 45.0], [3.0, -4.0, 2.0], [0.0, 30.0, 70.0], problem.scales.time_s)
    s = np.linspace(0.0, traj.t[-1], 57)
    assert np.allclose(bank_profile_at(traj, s), [bank_profile(traj, x) for x in s], atol=1e-15)
    # the end is integrated from the last interval's node: -30 + 40 s * (-4 + 2) / 2 deg/s
    assert math.isclose(float(bank_profile_at(traj, s)[-1]), math.radians(-70.0), abs_tol=1e-12)
