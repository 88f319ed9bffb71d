"""The multi-interval CGL collocation rows (integral form), the polynomial attitude path and the
mesh refinement helpers of the pseudospectral method.

Tolerances: the collocation and interpolation are exact for polynomials of their degree, so the
checks hold to rounding (1e-12 relative to values of order one, with the integration and
differentiation matrices' conditioning of a few hundred at these degrees).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from worker.solver.transcription.cgl import ChebyshevMesh, cgl_points, interpolate
from worker.solver.transcription.cgl_collocation import (
    CollocationPattern,
    PolynomialAttitude,
    PolynomialSamples,
    bernstein_from_cgl,
    degree_elevation,
)
from worker.solver.transcription.cgl_mesh_refine import carry, interval_errors, split

EXACT = 1e-12


def _mesh() -> ChebyshevMesh:
    return ChebyshevMesh(boundaries=(0.0, 0.2, 0.55, 1.0), degrees=(3, 5, 4))


def test_defects_vanish_on_a_polynomial_solution() -> None:
    """z(tau) = tau^3 + 2 tau, F = z' (degree 2 <= every interval's degree): zero residuals."""
    mesh = _mesh()
    pattern = CollocationPattern.of(mesh, 1, 0)
    tau = mesh.points(0.0, 1.0)
    z = (tau**3 + 2.0 * tau)[:, None]
    F = (3.0 * tau**2 + 2.0)[:, None]
    assert np.max(np.abs(pattern.defects(z, F))) < EXACT
    # a wrong rate at one point leaves a residual in its interval's rows
    F_bad = F.copy()
    F_bad[5] += 1.0
    assert np.max(np.abs(pattern.defects(z, F_bad))) > 1e-3


def test_one_row_block_per_new_point() -> None:
    """The integral form collocates each point but the first once: K - 1 row blocks."""
    mesh = _mesh()
    pattern = CollocationPattern.of(mesh, 8, 2)
    z = np.zeros((mesh.num_points, 8))
    assert pattern.defects(z, z).shape == (mesh.num_points - 1, 8)
    assert pattern.num_points == mesh.num_points == 13


def test_attitude_interpolates_and_differentiates_exactly() -> None:
    """Bank and alpha quadratic in time: the path returns their values and exact rates."""
    mesh = _mesh()
    tf = 2.5
    t = mesh.points(0.0, tf)
    bank = 0.3 + 0.1 * t - 0.05 * t**2
    alpha = np.radians(20.0) + 0.02 * t**2
    path = PolynomialAttitude(mesh, tf, bank, alpha)
    s = np.linspace(0.0, tf, 37)
    b, a_deg = path.at(s)
    assert np.allclose(b, 0.3 + 0.1 * s - 0.05 * s**2, atol=EXACT)
    assert np.allclose(np.radians(a_deg), np.radians(20.0) + 0.02 * s**2, atol=EXACT)
    db, da = path.rates_at(s)
    assert np.allclose(db, 0.1 - 0.1 * s, atol=1e-11)
    assert np.allclose(da, 0.04 * s, atol=1e-11)


def test_split_at_the_middle_or_at_an_inner_peak_within_budget() -> None:
    mesh = _mesh()
    marked = np.array([True, False, True])
    peaks = np.array([np.nan, np.nan, 0.7])
    new = split(mesh, marked, peaks, max_points=100)
    assert new.boundaries == pytest.approx((0.0, 0.1, 0.2, 0.55, 0.55 + 0.7 * 0.45, 1.0))
    assert new.degrees == (3, 3, 5, 4, 4)
    # a budget for one split only: the first marked interval is split, the second kept
    one = split(mesh, marked, peaks, max_points=mesh.num_points + 3)
    assert one.num_intervals == 4 and one.num_points == mesh.num_points + 3
    # a peak at the edge of its interval splits at the middle instead
    edge = split(mesh, np.array([False, True, False]), np.array([np.nan, 0.05, np.nan]), 100)
    assert edge.boundaries[2] == pytest.approx(0.375)


def test_carry_keeps_a_polynomial_exactly() -> None:
    mesh = _mesh()
    new = split(mesh, np.array([True, True, True]), np.full(3, np.nan), 100)
    tf = 3.0
    f = lambda t: 1.0 - t + 0.25 * t**3  # noqa: E731  degree 3 = the smallest degree
    moved = carry(mesh, new, tf, f(mesh.points(0.0, tf)))
    assert np.allclose(moved, f(new.points(0.0, tf)), atol=EXACT)


def test_interval_errors_measure_each_interval_from_its_first_point() -> None:
    """y' = 1 from each interval's first point: a shared boundary point moved by 0.3 shows as the
    end error of the interval it ends and of the one it starts (flown from it, that one ends
    0.3 away from its unmoved last point), not elsewhere (integration tolerance 1e-9)."""
    mesh = _mesh()
    tf = 1.0
    t = mesh.points(0.0, tf)
    z = t[:, None].copy()
    units = np.array([2.0])

    def rates(time: np.ndarray, y: np.ndarray, attitude: np.ndarray) -> np.ndarray:
        return np.ones_like(y)

    def attitude(time: np.ndarray) -> np.ndarray:
        return np.zeros((time.size, 2))

    assert np.max(interval_errors(mesh, tf, z, rates, attitude, units, 1)) < 1e-8
    last_of_second = mesh.interval_slices()[1].stop - 1
    z[last_of_second] += 0.3
    errors = interval_errors(mesh, tf, z, rates, attitude, units, 1)
    assert errors[1] == pytest.approx(0.15, abs=1e-8)
    assert errors[2] == pytest.approx(0.15, abs=1e-8)
    assert errors[0] < 1e-8


def test_a_bank_rate_peak_marks_its_interval_and_where_it_peaks() -> None:
    """A 30 deg bank bump at one point inside interval 2 of 5 (46.9 s of a 100 s flight, its
    neighbours 2.8 s away at 0: the interval's polynomial turns at about 10 deg/s against the
    scenario's 5 deg/s) at a quiet flight condition (80 km, 2 km/s: every path limit far away):
    only interval 2 shows an excess, and it peaks next to the bump."""
    import copy
    import math

    from app.schemas import ProblemDocument
    from worker.solver.methods.hp_scp.linearization import HpIterate
    from worker.solver.methods.hp_scp.mesh_update import between_points_excess
    from worker.solver.problem import build_problem
    from worker.solver.scenarios import get_scenario

    problem = build_problem(
        ProblemDocument.model_validate(copy.deepcopy(get_scenario("rlv-min-time-hp").problem))
    )
    sc = problem.scales
    mesh = ChebyshevMesh.uniform(5, 10)
    tf = 100.0 / sc.time_s
    t = mesh.points(0.0, tf)
    z = np.zeros((mesh.num_points, 8))
    z[:, 0] = 1.0 + 80e3 / sc.radius_m
    z[:, 3] = 2000.0 / sc.speed_m_s
    z[:, 7] = math.radians(10.0)
    bump = int(np.argmin(np.abs(t * sc.time_s - 46.9)))  # a point inside interval 2 (40-60 s)
    z[bump, 6] = math.radians(30.0)
    ref = HpIterate(z, np.zeros((mesh.num_points, 2)), tf, CollocationPattern.of(mesh, 8, 2))
    excess, peak = between_points_excess(problem, ref)
    assert excess[2] > 0.1
    assert np.all(excess[[0, 1, 3, 4]] == 0.0)
    assert 0.1 < peak[2] < 0.6  # beside the bump at 0.35 of the interval


def test_the_curvature_blocks_are_the_clipped_hessian_of_the_rows_lagrangian() -> None:
    """At one point: -d2(mu . F)/dx2 in scaled (z, w) units by central second differences of
    the dynamics, eigen-clipped, against the method's blocks (central differences of the
    analytic Jacobians). Tolerance 1e-3 relative to the block's largest entry: the reference
    second differences themselves move by up to 2e-4 of it between steps 1e-5 and 3e-4
    (scaled units; measured), the radius's exponential density dominating."""
    import copy

    from app.schemas import ProblemDocument
    from worker.solver.methods.hp_scp.linearization import HpIterate, curvature_blocks
    from worker.solver.models.alpha_bank_state import alpha_bank_state_dynamics
    from worker.solver.models.layout import ALPHA_BANK_STATE
    from worker.solver.problem import build_problem
    from worker.solver.scenarios import get_scenario

    problem = build_problem(
        ProblemDocument.model_validate(copy.deepcopy(get_scenario("rlv-min-time-hp").problem))
    )
    sc = problem.scales
    z = np.array([[1.0 + 60e3 / sc.radius_m, 0.1, 0.5, 0.8, -0.02, 0.3, 0.4, np.radians(25.0)]])
    w = np.array([[0.01, -0.005]])
    tf = 1.5
    mu = np.array([[0.3, -0.2, 0.5, 1.1, -0.7, 0.4, 0.05, -0.02]])
    units = np.concatenate([ALPHA_BANK_STATE.trust_units(sc), np.full(2, 0.02)])
    mesh = ChebyshevMesh.uniform(1, 1)
    ref = HpIterate(np.repeat(z, 2, 0), np.repeat(w, 2, 0), tf, CollocationPattern.of(mesh, 8, 2))
    blocks = curvature_blocks(problem, ref, np.repeat(mu, 2, 0), units)

    def phi(y: np.ndarray) -> float:
        x = y * units  # scaled -> nondimensional
        d = alpha_bank_state_dynamics(
            x[None, :8], x[None, 8:], problem.forces, problem.omega, tf, jacobians=False
        )
        return float(mu[0] @ d.F[0])

    y0 = np.concatenate([z[0], w[0]]) / units
    h = 3e-4
    H = np.empty((10, 10))
    for i in range(10):
        for j in range(10):
            e_i, e_j = np.eye(10)[i] * h, np.eye(10)[j] * h
            H[i, j] = (
                phi(y0 + e_i + e_j)
                - phi(y0 + e_i - e_j)
                - phi(y0 - e_i + e_j)
                + phi(y0 - e_i - e_j)
            ) / (4 * h * h)
    vals, vecs = np.linalg.eigh(-0.5 * (H + H.T))
    expected = vecs @ np.diag(np.maximum(vals, 0.0)) @ vecs.T
    assert np.max(np.abs(blocks[0] - expected)) <= 1e-3 * np.max(np.abs(expected))
    assert np.min(np.linalg.eigvalsh(blocks[0])) >= -1e-12


def test_bernstein_coefficients_reproduce_the_interpolant_and_bound_it() -> None:
    """The Bernstein form from CGL values is the same polynomial (rounding only: degree 6, order-one
    values), its end coefficients are its end values, and (elevated or not) its coefficients
    enclose its range."""
    n = 6
    tau = cgl_points(n)
    values = np.sin(3.0 * tau) + 0.3 * tau  # extrema inside the interval
    c = bernstein_from_cgl(n) @ values
    x = np.linspace(-1.0, 1.0, 401)
    s = 0.5 * (x + 1.0)
    basis = np.array([math.comb(n, j) * s**j * (1 - s) ** (n - j) for j in range(n + 1)]).T
    assert np.allclose(basis @ c, interpolate(values, n, x), atol=1e-13)
    assert c[0] == pytest.approx(values[0], abs=1e-14) and c[-1] == pytest.approx(values[-1])
    curve = interpolate(values, n, x)
    for m in (0, 3, n):
        elevated = degree_elevation(n, m) @ c
        assert elevated.min() <= curve.min() + 1e-12 and elevated.max() >= curve.max() - 1e-12
    # elevation narrows the hull towards the range
    width = [np.ptp(degree_elevation(n, m) @ c) for m in (0, n, 4 * n)]
    assert width[0] > width[1] > width[2] > np.ptp(curve)


def test_polynomial_samples_give_the_interpolant_and_its_slope_hull() -> None:
    """On a two-interval mesh: the between-point rows interpolate exactly, and the slope rows are
    the Bernstein coefficients of the polynomial's derivative in t / t_f, so they enclose the rate
    (times t_f) that the attitude polynomial flies."""
    mesh = ChebyshevMesh((0.0, 0.4, 1.0), (4, 6))
    tf = 2.0
    t = mesh.points(0.0, tf)
    x = np.sin(3.0 * t / tf) + 0.2 * t
    samples = PolynomialSamples.of(mesh, per_gap=2, elevated=True)
    attitude = PolynomialAttitude(mesh, tf, x, x)
    at = np.sum(samples.between * x[samples.between_idx], axis=1)
    edges = mesh.interval_times(0.0, tf)
    times = []
    for k, n in enumerate(mesh.degrees):
        tau = cgl_points(n)
        share = np.array([1.0, 2.0]) / 3.0
        mid = (tau[:-1, None] + share[None, :] * np.diff(tau)[:, None]).ravel()
        times.extend(0.5 * (edges[k] * (1 - mid) + edges[k + 1] * (1 + mid)))
    bank, _ = attitude.at(np.array(times))
    assert np.allclose(at, bank, atol=1e-14)
    slopes = np.sum(samples.slope * x[samples.slope_idx], axis=1) / tf
    first = 2 * mesh.degrees[0]  # the first interval's rows: its derivative at degree 2n - 1
    for k, rows in enumerate((slopes[:first], slopes[first:])):
        inside = np.linspace(edges[k], edges[k + 1], 301)[1:-1]
        rate, _ = attitude.rates_at(inside)
        assert rows.min() <= rate.min() + 1e-12 and rows.max() >= rate.max() - 1e-12
