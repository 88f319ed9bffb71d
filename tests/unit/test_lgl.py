"""Legendre-Gauss-Lobatto operators: exact on polynomials of their degree (the properties the
integral-form collocation of paper 004's phases rests on)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.polynomial import Polynomial

from worker.solver.transcription.lgl import (
    LglMesh,
    differentiation_matrix,
    integration_matrix,
    interpolate,
    lgl_points,
    lgl_weights,
)

# roundoff of O(n^2) operations on O(1) numbers of degree <= 12: 1e-12 is 1e4 x machine epsilon
TOL = 1e-12


@pytest.mark.parametrize("n", [1, 2, 3, 4, 6, 9, 12])
def test_points_are_the_roots_of_the_legendre_derivative_with_the_ends(n: int) -> None:
    x = lgl_points(n)
    assert x[0] == -1.0 and x[-1] == 1.0 and np.all(np.diff(x) > 0)
    legendre_n = np.polynomial.legendre.Legendre.basis(n)
    assert np.abs(legendre_n.deriv()(x[1:-1])).max(initial=0.0) < 1e-10
    assert np.allclose(x, -x[::-1], atol=0, rtol=0)  # exactly symmetric


@pytest.mark.parametrize("n", [1, 2, 3, 4, 6, 9, 12])
def test_quadrature_is_exact_to_degree_2n_minus_1(n: int) -> None:
    x, w = lgl_points(n), lgl_weights(n)
    for k in range(2 * n):
        exact = (1.0 - (-1.0) ** (k + 1)) / (k + 1)
        assert abs(w @ x**k - exact) < TOL
    if n >= 2:  # and not beyond: x^(2n) is not integrated exactly
        k = 2 * n
        assert abs(w @ x**k - 2.0 / (k + 1)) > 1e3 * TOL


@pytest.mark.parametrize("n", [1, 2, 4, 7, 12])
def test_differentiation_and_integration_are_exact_on_degree_n(n: int) -> None:
    rng = np.random.default_rng(n)
    p = Polynomial(rng.normal(size=n + 1))
    x = lgl_points(n)
    D, A = differentiation_matrix(n), integration_matrix(n)
    assert np.abs(D @ p(x) - p.deriv()(x)).max() < 1e-10 * max(1.0, n**2)
    dp = p.deriv()
    assert np.abs(A @ dp(x) - (p(x) - p(-1.0))).max() < TOL * 10
    assert np.abs(A[-1] - lgl_weights(n)).max() < TOL  # the last row is the quadrature


def test_interpolation_is_exact_on_degree_n_and_at_the_points() -> None:
    n = 5
    x = lgl_points(n)
    p = Polynomial([0.3, -1.0, 0.5, 2.0, -0.7, 0.1])
    s = np.linspace(-1.0, 1.0, 37)
    assert np.abs(interpolate(n, p(x), s) - p(s)).max() < TOL
    assert np.array_equal(interpolate(n, p(x), x), p(x))
    two = np.column_stack([p(x), 2.0 * p(x)])
    assert np.abs(interpolate(n, two, s)[:, 1] - 2.0 * p(s)).max() < 10 * TOL


def test_a_mesh_shares_segment_ends_and_integrates_piecewise_polynomials() -> None:
    mesh = LglMesh(np.array([0.0, 0.2, 0.7, 1.0]), 4)
    assert mesh.points == 13
    assert np.all(np.diff(mesh.s) > 0) and mesh.s[0] == 0.0 and mesh.s[-1] == 1.0
    assert mesh.s[4] == pytest.approx(0.2) and mesh.s[8] == pytest.approx(0.7)
    f = np.exp(mesh.s)
    assert abs(mesh.quadrature @ f - (np.e - 1.0)) < 1e-7  # degree-4 pieces on exp: O(h^8)
    values = np.column_stack([mesh.s**3, np.sin(mesh.s)])
    t = np.linspace(0.0, 1.0, 50)
    out = mesh.at(values, t)
    assert np.abs(out[:, 0] - t**3).max() < TOL * 10  # cubic: exact per segment
    assert np.abs(out[:, 1] - np.sin(t)).max() < 1e-5


@pytest.mark.parametrize(
    "breaks", [np.array([0.0, 0.5]), np.array([0.0, 0.6, 0.4, 1.0]), np.array([0.1, 1.0])]
)
def test_a_mesh_refuses_breaks_that_do_not_span_the_phase(breaks: np.ndarray) -> None:
    with pytest.raises(ValueError, match="breaks"):
        LglMesh(breaks, 3)


def test_degrees_below_one_are_refused() -> None:
    with pytest.raises(ValueError, match="degree"):
        lgl_points(0)
    with pytest.raises(ValueError, match="segment"):
        LglMesh.uniform(0, 3)
