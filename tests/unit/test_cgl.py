"""CGL discretization (worker.solver.transcription.cgl): differentiation, quadrature, integration
and interpolation exact on polynomials, and the multi-interval mesh built from them.

Every reference value comes from numpy.polynomial (exact derivatives and antiderivatives of the
test polynomials), never from the module's own outputs. Tolerances are multiples of the double
precision unit roundoff EPS, scaled the way roundoff grows for each operator.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.polynomial import Chebyshev, Polynomial

from worker.solver.transcription.cgl import (
    ChebyshevMesh,
    barycentric_weights,
    cgl_points,
    clenshaw_curtis_weights,
    differentiation_matrix,
    integration_matrix,
    interpolate,
)

EPS = float(np.finfo(float).eps)
DEGREES = [1, 2, 5, 10, 20, 40]


def d_tol(n: int, scale: float) -> float:
    """Roundoff of D f: entries of D grow like n^2, so the error does too, relative to the size
    of the derivative; 10x margin over the ~0.6 n^2 EPS measured up to n = 40."""
    return 10.0 * n**2 * EPS * max(1.0, scale)


# ---------------------------------------------------------------- points, D


@pytest.mark.parametrize("n", DEGREES)
def test_points_increasing_with_exact_ends(n: int) -> None:
    tau = cgl_points(n)
    assert tau.shape == (n + 1,)
    assert tau[0] == -1.0 and tau[-1] == 1.0  # exact: the mesh relies on exact interval ends
    assert np.all(np.diff(tau) > 0.0)
    # the defining formula, to a few ulps (the module evaluates it in an equivalent sine form)
    np.testing.assert_allclose(tau, -np.cos(np.pi * np.arange(n + 1) / n), rtol=0, atol=4 * EPS)


@pytest.mark.parametrize("n", DEGREES)
def test_differentiation_exact_on_monomials(n: int) -> None:
    tau = cgl_points(n)
    D = differentiation_matrix(n)
    assert D.shape == (n + 1, n + 1)
    for m in range(n + 1):
        p = Polynomial.basis(m)
        exact = p.deriv()(tau)
        err = np.abs(D @ p(tau) - exact).max()
        assert err <= d_tol(n, np.abs(exact).max()), (n, m, err)


@pytest.mark.parametrize("n", DEGREES)
def test_differentiation_exact_on_chebyshev_polynomials(n: int) -> None:
    tau = cgl_points(n)
    D = differentiation_matrix(n)
    for m in range(n + 1):
        T = Chebyshev.basis(m)
        exact = T.deriv()(tau)  # up to m^2 at the ends
        err = np.abs(D @ T(tau) - exact).max()
        assert err <= d_tol(n, np.abs(exact).max()), (n, m, err)


@pytest.mark.parametrize("n", DEGREES)
def test_differentiation_of_a_constant_is_zero(n: int) -> None:
    D = differentiation_matrix(n)
    # the negative-sum diagonal makes each row sum vanish up to the roundoff of re-summing it in
    # another order: n terms of size up to ~n^2, so n^2 EPS again (measured <= 0.64 n^2 EPS)
    assert np.abs(D @ np.full(n + 1, 3.0)).max() <= d_tol(n, 3.0)


def test_base_operators_are_cached_and_read_only() -> None:
    assert differentiation_matrix(7) is differentiation_matrix(7)
    for a in (
        cgl_points(7),
        differentiation_matrix(7),
        clenshaw_curtis_weights(7),
        integration_matrix(7),
        barycentric_weights(7),
    ):
        assert not a.flags.writeable
    with pytest.raises(ValueError):
        differentiation_matrix(7)[0, 0] = 1.0


@pytest.mark.parametrize("bad", [0, -3, 2.0, True])
def test_degree_must_be_a_positive_integer(bad: object) -> None:
    with pytest.raises(ValueError, match="integer >= 1"):
        cgl_points(bad)  # type: ignore[arg-type]


# ---------------------------------------------------------------- quadrature, B


def exact_integral(p: Polynomial | Chebyshev, a: float = -1.0, b: float = 1.0) -> float:
    q = p.integ()
    return float(q(b) - q(a))


@pytest.mark.parametrize("n", DEGREES)
def test_clenshaw_curtis_exact_up_to_degree_n(n: int) -> None:
    tau = cgl_points(n)
    w = clenshaw_curtis_weights(n)
    assert w.shape == (n + 1,)
    assert np.all(w > 0.0)  # Clenshaw–Curtis weights are positive (Imhof 1963)
    # the weights sum to 2 up to the roundoff of n + 1 additions of O(1) terms
    assert abs(w.sum() - 2.0) <= 4 * (n + 1) * EPS
    for m in range(n + 1):
        # T_m kept in the Chebyshev basis (its monomial form loses digits to cancellation)
        for p in (Polynomial.basis(m), Chebyshev.basis(m)):
            # positive weights summing to 2, values bounded by 1: error a few EPS (measured 2 EPS)
            assert abs(w @ p(tau) - exact_integral(p)) <= 20 * EPS, (n, m)


def test_clenshaw_curtis_converges_spectrally() -> None:
    exact = math.e - 1.0 / math.e
    errors = [abs(clenshaw_curtis_weights(n) @ np.exp(cgl_points(n)) - exact) for n in (2, 4, 8)]
    # geometric (faster than any power) convergence for an entire function: each doubling of n
    # gains far more than the factor 2^p of a fixed order p (observed: ~400, then ~1e6)
    assert errors[0] > 100 * errors[1] > 100**2 * errors[2]
    # by n = 16 the error is at roundoff: a few EPS on an integral of size ~2.35
    assert abs(clenshaw_curtis_weights(16) @ np.exp(cgl_points(16)) - exact) <= 20 * EPS
    # a smooth non-entire function (pole at +-i/4): still geometric, with a slower rate
    runge = 0.5 * math.atan(4.0)  # int_{-1}^{1} 1 / (1 + 16 t^2) dt
    err = [
        abs(clenshaw_curtis_weights(n) @ (1.0 / (1.0 + 16.0 * cgl_points(n) ** 2)) - runge)
        for n in (10, 20, 40, 80)
    ]
    assert err[0] > err[1] > err[2] > err[3]
    # the rate is set by the Bernstein ellipse through the pole, rho = 1/4 + sqrt(1/16 + 1) ~ 1.28;
    # Clenshaw–Curtis behaves like rho^(-2n) here (Trefethen 2008): ~2.5e-9 at n = 40 (observed
    # 5e-9), roundoff level (observed 9e-15) at n = 80; 10x margins for the constants
    assert err[2] < 5e-8
    assert err[3] < 1e-13


@pytest.mark.parametrize("n", DEGREES)
def test_integration_matrix_exact_on_polynomials(n: int) -> None:
    tau = cgl_points(n)
    B = integration_matrix(n)
    assert B.shape == (n + 1, n + 1)
    rng = np.random.default_rng(n)
    polys: list[Polynomial | Chebyshev] = [Polynomial.basis(m) for m in range(n + 1)]
    polys += [Polynomial(rng.standard_normal(n + 1)) for _ in range(3)]
    polys += [Chebyshev.basis(n), Chebyshev(rng.standard_normal(n + 1))]
    for f in polys:
        df = f.deriv()(tau)
        exact = f(tau) - f(-1.0)
        # B has O(1) entries summing over n + 1 derivative values of size up to max|f'|, and the
        # Chebyshev transform inside adds a factor ~n: bounded by the n^2 growth of d_tol
        # (measured <= 0.5 n^2 EPS max|f'|)
        assert np.abs(B @ df - exact).max() <= d_tol(n, np.abs(df).max())
    assert np.all(B[0] == 0.0)  # int_{-1}^{-1} is exactly empty


@pytest.mark.parametrize("n", DEGREES)
def test_integration_matrix_last_row_is_the_quadrature(n: int) -> None:
    # two different constructions (DCT + antiderivative vs Waldvogel's cosine sum) of the same
    # numbers, each O(1): agree to a few EPS
    np.testing.assert_allclose(
        integration_matrix(n)[-1], clenshaw_curtis_weights(n), rtol=0, atol=20 * EPS
    )


# ---------------------------------------------------------------- interpolation


@pytest.mark.parametrize("n", DEGREES)
def test_interpolation_reproduces_polynomials(n: int) -> None:
    rng = np.random.default_rng(100 + n)
    tau = cgl_points(n)
    ps = [Polynomial(rng.standard_normal(n + 1)), Chebyshev.basis(n)]
    values = np.column_stack([p(tau) for p in ps])
    t = np.concatenate([rng.uniform(-1.0, 1.0, 50), [-1.0, 1.0, 0.999999999, -1.0 + 1e-15]])
    got = interpolate(values, n, t)
    assert got.shape == (t.size, 2)
    for j, p in enumerate(ps):
        # the second-kind barycentric formula is forward stable on CGL points (Higham 2004):
        # error ~ Lebesgue constant (~ log n) x EPS x |values|; the random-coefficient polynomial
        # has values up to ~n, so allow 100 EPS times that size
        scale = max(1.0, np.abs(p(t)).max())
        np.testing.assert_allclose(got[:, j], p(t), rtol=0, atol=100 * EPS * scale)
    one = interpolate(values[:, 0], n, t)
    assert one.shape == t.shape
    # same formula on one column: only the summation order of the matrix product may differ
    np.testing.assert_allclose(one, got[:, 0], rtol=0, atol=100 * EPS * np.abs(one).max())


@pytest.mark.parametrize("n", DEGREES)
def test_interpolation_hits_nodes_exactly(n: int) -> None:
    rng = np.random.default_rng(n)
    values = rng.standard_normal((n + 1, 3))
    tau = cgl_points(n)
    np.testing.assert_array_equal(interpolate(values, n, tau), values)  # exact, no arithmetic
    np.testing.assert_array_equal(
        interpolate(values, n, tau[::-1].reshape(-1, 1))[:, 0], values[::-1]
    )
    assert interpolate(values[:, 0], n, float(tau[1])).shape == ()
    assert float(interpolate(values[:, 0], n, float(tau[1]))) == values[1, 0]


def test_interpolation_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match="shape"):
        interpolate(np.zeros(4), 4, 0.0)
    with pytest.raises(ValueError, match=r"\[-1, 1\]"):
        interpolate(np.zeros(5), 4, 1.5)
    with pytest.raises(ValueError, match=r"\[-1, 1\]"):
        interpolate(np.zeros(5), 4, np.nan)


# ---------------------------------------------------------------- mesh


@pytest.mark.parametrize(
    ("boundaries", "degrees", "message"),
    [
        ((0.0, 0.5, 0.5, 1.0), (3, 3, 3), "strictly increasing"),
        ((0.0, 0.7, 0.3, 1.0), (3, 3, 3), "strictly increasing"),
        ((0.1, 0.5, 1.0), (3, 3), "start at 0"),
        ((0.0, 0.5, 0.9), (3, 3), "end at 1"),
        ((0.0, 0.5, 1.0), (3, 0), "integer >= 1"),
        ((0.0, 0.5, 1.0), (3, 2.5), "integer >= 1"),
        ((0.0, 0.5, 1.0), (3,), "one degree per interval"),
        ((0.0,), (), "at least two"),
        ((0.0, math.nan, 1.0), (3, 3), "finite"),
    ],
)
def test_mesh_validation(
    boundaries: tuple[float, ...], degrees: tuple[int, ...], message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        ChebyshevMesh(boundaries=boundaries, degrees=degrees)


def test_mesh_uniform_and_counts() -> None:
    mesh = ChebyshevMesh.uniform(4, 6)
    assert mesh.boundaries == (0.0, 0.25, 0.5, 0.75, 1.0)
    assert mesh.degrees == (6, 6, 6, 6)
    assert mesh.num_intervals == 4
    assert mesh.num_points == 4 * 6 + 1
    with pytest.raises(ValueError, match="intervals"):
        ChebyshevMesh.uniform(0, 6)
    single = ChebyshevMesh.uniform(1, 9)  # the single-interval special case
    # the affine map to [-1, 1] itself: the CGL points up to an ulp
    np.testing.assert_allclose(single.points(-1.0, 1.0), cgl_points(9), rtol=0, atol=2 * EPS)
    np.testing.assert_array_equal(
        single.differentiation_matrices(-1.0, 1.0)[0], differentiation_matrix(9)
    )
    np.testing.assert_array_equal(single.quadrature_weights(-1.0, 1.0), clenshaw_curtis_weights(9))


MESH = ChebyshevMesh(boundaries=[0.0, 0.1, 0.45, 1.0], degrees=[4, 7, 5])  # type: ignore[arg-type]
T0, TF = 3.0, 10.0  # a span != [-1, 1]: the scaling by h_k / 2 matters


def test_mesh_points_share_boundaries() -> None:
    assert MESH.boundaries == (0.0, 0.1, 0.45, 1.0)  # lists normalized to tuples (hashable)
    assert MESH.num_points == 4 + 7 + 5 + 1
    t = MESH.points(T0, TF)
    edges = MESH.interval_times(T0, TF)
    assert t.shape == (MESH.num_points,)
    assert t[0] == T0 and t[-1] == TF  # exact: (a (1 - tau) + b (1 + tau)) / 2 at tau = +-1
    assert np.all(np.diff(t) > 0.0)  # distinct and increasing
    slices = MESH.interval_slices()
    assert [(s.start, s.stop) for s in slices] == [(0, 5), (4, 12), (11, 17)]
    for k, (n, s) in enumerate(zip(MESH.degrees, slices, strict=True)):
        local = t[s]
        assert local[0] == edges[k] and local[-1] == edges[k + 1]  # shared points exact
        a, b = T0 + (TF - T0) * MESH.boundaries[k], T0 + (TF - T0) * MESH.boundaries[k + 1]
        # each interval's points are the affine image of the CGL points (a few ulps of t ~ 10)
        expect = a + (b - a) * (np.polynomial.chebyshev.chebpts2(n + 1) + 1.0) / 2.0
        np.testing.assert_allclose(local, expect, rtol=0, atol=8 * EPS * TF)


def continuous_pieces(degrees: tuple[int, ...], bump: int = 0) -> list[Polynomial]:
    """One random polynomial of degree n_k per interval of MESH on [T0, TF] (``bump`` adds one
    degree to the last), each in its interval's own scaled variable (numpy's domain/window, so
    the values stay well conditioned), shifted to be continuous at the boundaries (kinks there)."""
    rng = np.random.default_rng(sum(degrees) + bump)
    edges = T0 + (TF - T0) * np.asarray(MESH.boundaries)
    pieces: list[Polynomial] = []
    for k, n in enumerate(degrees):
        deg = n + bump if k == len(degrees) - 1 else n
        p = Polynomial(rng.standard_normal(deg + 1), domain=[edges[k], edges[k + 1]])
        if pieces:
            p = p + (pieces[-1](edges[k]) - p(edges[k]))
        pieces.append(p)
    return pieces


def evaluate_pieces(pieces: list[Polynomial], t: np.ndarray) -> np.ndarray:
    edges = T0 + (TF - T0) * np.asarray(MESH.boundaries)
    k = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, len(pieces) - 1)
    out = np.empty(t.shape)
    for j, p in enumerate(pieces):
        out[k == j] = p(t[k == j])
    return out


def test_composite_quadrature_exact_for_piecewise_polynomials() -> None:
    w = MESH.quadrature_weights(T0, TF)
    t = MESH.points(T0, TF)
    assert w.shape == (MESH.num_points,)
    assert np.all(w > 0.0)
    # positive weights summing to the span length: its roundoff is a few EPS relative
    assert abs(w.sum() - (TF - T0)) <= 20 * EPS * (TF - T0)
    # a global polynomial of degree min(degrees) = 4 across unequal intervals
    g = Polynomial(np.random.default_rng(7).standard_normal(5), domain=[T0, TF])
    tol = 100 * EPS * (TF - T0) * np.abs(g(t)).max()  # positive weights: EPS x span x max|f|
    assert abs(w @ g(t) - exact_integral(g, T0, TF)) <= tol
    # continuous piecewise polynomial of degrees (4, 7, 5), kinks at the boundaries
    edges = MESH.interval_times(T0, TF)
    pieces = continuous_pieces(MESH.degrees)
    f = evaluate_pieces(pieces, t)
    exact = sum(
        exact_integral(p, a, b) for p, a, b in zip(pieces, edges[:-1], edges[1:], strict=True)
    )
    assert abs(w @ f - exact) <= 100 * EPS * (TF - T0) * np.abs(f).max()
    # one degree more on the last (odd-degree) interval is not integrated exactly: the check has
    # teeth (the error is ~5e-4, far above the roundoff tolerance)
    bad = continuous_pieces(MESH.degrees, bump=1)
    f_bad = evaluate_pieces(bad, t)
    exact_bad = sum(
        exact_integral(p, a, b) for p, a, b in zip(bad, edges[:-1], edges[1:], strict=True)
    )
    assert abs(w @ f_bad - exact_bad) > 1e-8


def test_interval_differentiation_scaled_to_the_span() -> None:
    t = MESH.points(T0, TF)
    Ds = MESH.differentiation_matrices(T0, TF)
    h = np.diff(MESH.interval_times(T0, TF))
    pieces = continuous_pieces(MESH.degrees)
    for k, (D, n, s) in enumerate(zip(Ds, MESH.degrees, MESH.interval_slices(), strict=True)):
        assert D.shape == (n + 1, n + 1)
        p = pieces[k]  # numpy's deriv applies the domain scaling itself: an independent d/dt
        exact = p.deriv()(t[s])
        # the n^2 roundoff of D on the local derivative, scaled by the same 2 / h_k
        err = np.abs(D @ p(t[s]) - exact).max()
        assert err <= d_tol(n, np.abs(exact).max() * h[k] / 2.0) * 2.0 / h[k], (k, err)


def test_mesh_interpolation_piecewise_exact() -> None:
    t = MESH.points(T0, TF)
    pieces = continuous_pieces(MESH.degrees)
    values = np.column_stack([evaluate_pieces(pieces, t), -2.0 * evaluate_pieces(pieces, t)])
    rng = np.random.default_rng(3)
    x = np.concatenate([rng.uniform(T0, TF, 60), MESH.interval_times(T0, TF), t])
    expect = evaluate_pieces(pieces, x)
    got = MESH.interpolate(values, T0, TF, x)
    assert got.shape == (x.size, 2)
    # barycentric formula forward stable: EPS x a small Lebesgue factor x |values|
    scale = np.abs(expect).max()
    np.testing.assert_allclose(got[:, 0], expect, rtol=0, atol=100 * EPS * scale)
    np.testing.assert_allclose(got[:, 1], -2.0 * expect, rtol=0, atol=200 * EPS * scale)
    assert MESH.interpolate(values[:, 0], T0, TF, x[:60].reshape(4, 15)).shape == (4, 15)
    assert MESH.interpolate(values[:, 0], T0, TF, TF).shape == ()
    with pytest.raises(ValueError, match="lie in"):
        MESH.interpolate(values, T0, TF, TF + 0.1)
    with pytest.raises(ValueError, match="shape"):
        MESH.interpolate(values[:-1], T0, TF, T0)
    with pytest.raises(ValueError, match="tf > t0"):
        MESH.points(TF, T0)
