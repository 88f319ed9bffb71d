"""Exact FOH discretization (paper 002 Theorem 1, eq. 24) and bank-state Jacobians.

Ground truth for the propagation is scipy's DOP853 at rtol 1e-11 on each interval; the analytic
Jacobians are checked against the complex step (exact to round-off, so 1e-8 relative is loose).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from app.schemas import ProblemDocument
from worker.solver.models.bank_state import bank_state_dynamics
from worker.solver.problem import EntryProblem, build_problem
from worker.solver.scenarios import get_scenario
from worker.solver.transcription.foh_exact import foh_exact, propagate_nodes
from worker.solver.transcription.time_grid import initial_reference

RTOL = 1e-8  # issue acceptance for analytic Jacobians vs complex step


@pytest.fixture(scope="module")
def problem() -> EntryProblem:
    raw = dict(get_scenario("rlv-max-terminal-velocity").problem)
    return build_problem(ProblemDocument.model_validate(raw))


def _reference(problem: EntryProblem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 16-node reference with unequal intervals (64-150 s, within Delta_max) and a bank rate
    that changes sign."""
    ref = initial_reference(problem, 16, 20.0)
    s = ref.s * np.linspace(0.6, 1.4, ref.s.size)
    s *= ref.s.sum() / s.sum()
    w = np.radians(0.2) * problem.scales.time_s * np.cos(np.arange(16))
    return ref.z, w, s


def test_propagation_matches_dop853(problem: EntryProblem) -> None:
    z, w, s = _reference(problem)
    maps = foh_exact(z, w, s, problem.forces, problem.omega, substeps=8)
    for k in range(s.size):

        def rhs(tau: float, x: np.ndarray, k: int = k) -> np.ndarray:
            wk = np.array([(1 - tau) * w[k] + tau * w[k + 1]])
            return bank_state_dynamics(
                x[None, :], wk, problem.forces, problem.omega, s[k], jacobians=False
            ).F[0]

        truth = solve_ivp(rhs, (0.0, 1.0), z[k], method="DOP853", rtol=1e-11, atol=1e-13).y[:, -1]
        err = np.abs(truth - maps.x_prop[k])
        # 8 RK4 substeps over intervals up to 150 s: per interval below 2 m in radius and
        # 0.05 m/s in speed, well inside the 25 m / 2 m/s terminal residual budget of Table 4
        assert err[0] * problem.scales.radius_m < 2.0
        assert err[3] * problem.scales.speed_m_s < 0.05
        assert math.degrees(float(np.max(err[[1, 2, 4, 5, 6]]))) < 5e-3  # angles: 0.005 deg


def test_zero_deviation_reproduces_propagation(problem: EntryProblem) -> None:
    """With the reference as its own solution the stitched dynamics (eq. 24) hold exactly when
    the nodes are the chained propagation: the right-hand side x_prop - z_{k+1} vanishes."""
    z, w, s = _reference(problem)
    chained = np.empty_like(z)
    chained[0] = z[0]
    for k in range(s.size):
        chained[k + 1] = propagate_nodes(
            chained[k : k + 2], w[k : k + 2], s[k : k + 1], problem.forces, problem.omega, 8
        )[0]
    maps = foh_exact(chained, w, s, problem.forces, problem.omega, substeps=8)
    assert np.max(np.abs(maps.x_prop - chained[1:])) < 1e-13  # same arithmetic: round-off only


def test_maps_match_finite_differences(problem: EntryProblem) -> None:
    """Phi, B-, B+, S against central differences of the propagation (step 1e-6, O(h^2) error)."""
    z, w, s = _reference(problem)
    maps = foh_exact(z, w, s, problem.forces, problem.omega, substeps=8)
    h = 1e-6
    k = 4

    def prop(z: np.ndarray, w: np.ndarray, s: np.ndarray) -> np.ndarray:
        return propagate_nodes(z, w, s, problem.forces, problem.omega, 8)

    def diff(make: object) -> np.ndarray:
        assert callable(make)
        return (prop(*make(h)) - prop(*make(-h))) / (2 * h)

    def bump_w(j: int) -> object:
        return lambda e: (z, w + e * (np.arange(w.size) == j), s)

    assert np.allclose(diff(bump_w(k))[k], maps.Bm[k], rtol=1e-5, atol=1e-7)
    assert np.allclose(diff(bump_w(k + 1))[k], maps.Bp[k], rtol=1e-5, atol=1e-7)
    ds = diff(lambda e: (z, w, s + e * (np.arange(s.size) == k)))
    assert np.allclose(ds[k], maps.S[k], rtol=1e-5, atol=1e-6)
    for j in range(z.shape[1]):
        e_j = np.zeros_like(z)
        e_j[k, j] = 1.0
        col = diff(lambda e, e_j=e_j: (z + e * e_j, w, s))[k]
        assert np.allclose(col, maps.Phi[k][:, j], rtol=1e-4, atol=1e-5)


def test_inner_samples_match_propagation_and_finite_differences(problem: EntryProblem) -> None:
    """The substeps kept for the between-node path rows: the state is the propagation
    from the node (DOP853, as above) and its maps are the derivatives of that state (central
    differences, same step and tolerances as the end-of-interval maps)."""
    z, w, s = _reference(problem)
    maps = foh_exact(z, w, s, problem.forces, problem.omega, substeps=8, samples=True)
    samples = maps.samples
    assert samples is not None and samples.x.shape == (s.size, 9, z.shape[1])
    k, j = 4, 3  # interval 4, tau = 3/8
    tau = j / 8

    def rhs(t: float, x: np.ndarray) -> np.ndarray:
        wk = np.array([(1 - t) * w[k] + t * w[k + 1]])
        return bank_state_dynamics(
            x[None, :], wk, problem.forces, problem.omega, s[k], jacobians=False
        ).F[0]

    truth = solve_ivp(rhs, (0.0, tau), z[k], method="DOP853", rtol=1e-11, atol=1e-13).y[:, -1]
    assert abs(truth[0] - samples.x[k, j, 0]) * problem.scales.radius_m < 2.0
    assert math.degrees(float(np.max(np.abs(truth - samples.x[k, j])[[1, 2, 4, 5, 6]]))) < 5e-3

    h = 1e-6

    def state(z: np.ndarray, w: np.ndarray, s: np.ndarray) -> np.ndarray:
        out = foh_exact(z, w, s, problem.forces, problem.omega, substeps=8, samples=True).samples
        assert out is not None
        return out.x[k, j]

    def diff(make: object) -> np.ndarray:
        assert callable(make)
        return (state(*make(h)) - state(*make(-h))) / (2 * h)

    unit_w = np.arange(w.size)
    assert np.allclose(diff(lambda e: (z, w + e * (unit_w == k), s)), samples.Bm[k, j], 1e-5, 1e-7)
    assert np.allclose(
        diff(lambda e: (z, w + e * (unit_w == k + 1), s)), samples.Bp[k, j], 1e-5, 1e-7
    )
    ds = diff(lambda e: (z, w, s + e * (np.arange(s.size) == k)))
    assert np.allclose(ds, samples.S[k, j], rtol=1e-5, atol=1e-6)
    for col in range(z.shape[1]):
        e_c = np.zeros_like(z)
        e_c[k, col] = 1.0
        d_col = diff(lambda e, e_c=e_c: (z + e * e_c, w, s))
        assert np.allclose(d_col, samples.Phi[k, j][:, col], rtol=1e-4, atol=1e-5)


def test_bank_state_jacobians_complex_step(problem: EntryProblem) -> None:
    rng = np.random.default_rng(3)
    n = 6
    z = np.column_stack(
        [
            1.0 + rng.uniform(20e3, 100e3, n) / problem.scales.radius_m,
            rng.uniform(-1, 1, n),
            rng.uniform(-1.2, 1.2, n),
            rng.uniform(0.15, 0.95, n),
            rng.uniform(-0.3, 0.1, n),
            rng.uniform(-3, 3, n),
            rng.uniform(-1.4, 1.4, n),
        ]
    )
    w = rng.uniform(-0.5, 0.5, n)
    s = rng.uniform(0.01, 0.2, n)
    d = bank_state_dynamics(z, w, problem.forces, problem.omega, s)
    assert d.A is not None and d.B is not None
    step = 1e-30
    for j in range(z.shape[1]):
        zc = z.astype(complex)
        zc[:, j] += 1j * step
        num = bank_state_dynamics(zc, w, problem.forces, problem.omega, s, jacobians=False)
        col = num.F.imag / step
        scale = np.maximum(np.abs(col), 1e-6 * np.max(np.abs(col)) + 1e-12)
        assert np.max(np.abs(d.A[:, :, j] - col) / scale) <= RTOL
    wc = w.astype(complex) + 1j * step
    num_w = bank_state_dynamics(z, wc, problem.forces, problem.omega, s, jacobians=False)
    assert np.allclose(d.B, num_w.F.imag / step, rtol=RTOL, atol=1e-14)
    sc = s.astype(complex) + 1j * step
    num_s = bank_state_dynamics(z, w, problem.forces, problem.omega, sc, jacobians=False)
    assert np.allclose(d.S, num_s.F.imag / step, rtol=RTOL, atol=1e-14)


def test_samples_end_at_the_node_and_the_propagated_end(problem: EntryProblem) -> None:
    """Sample 0 of every interval is its node with identity maps, the last is the interval's own
    end (x_prop and its maps): the between-node rows then cover the nodes too."""
    z, w, s = _reference(problem)
    maps = foh_exact(z, w, s, problem.forces, problem.omega, substeps=8, samples=True)
    both = maps.samples
    nz = z.shape[1]
    assert both is not None and both.x.shape == (s.size, 9, nz)
    assert np.array_equal(both.x[:, 0], z[:-1])
    assert np.array_equal(both.Phi[:, 0], np.broadcast_to(np.eye(nz), (s.size, nz, nz)))
    assert not np.any(both.Bm[:, 0]) and not np.any(both.Bp[:, 0]) and not np.any(both.S[:, 0])
    for name in ("Phi", "Bm", "Bp", "S"):
        assert np.array_equal(getattr(both, name)[:, -1], getattr(maps, name))
    assert np.array_equal(both.x[:, -1], maps.x_prop)
