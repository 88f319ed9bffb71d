"""Between-node rows of the time-domain SCP: the smooth maximum over an interval's samples.

Synthetic samples with random maps: the conservative row must bound the worst sample from above
by at most width x ln(J), the exact row must equal the worst sample, and in both the coefficients
must be the gradient of that smooth maximum carried through the samples' linear maps (checked by
central differences, exact for this smooth function up to O(h^2))."""

from __future__ import annotations

import numpy as np

from worker.solver.constraints.between_nodes import smooth_max_rows
from worker.solver.transcription.foh_exact import IntervalSamples

N, J, M, NZ = 3, 6, 2, 7


def _samples(rng: np.random.Generator) -> IntervalSamples:
    return IntervalSamples.from_parts(
        x=rng.normal(size=(N, J, NZ)),
        Phi=rng.normal(size=(N, J, NZ, NZ)),
        Bm=rng.normal(size=(N, J, NZ)),
        Bp=rng.normal(size=(N, J, NZ)),
        S=rng.normal(size=(N, J, NZ)),
    )


def _dense(grad: np.ndarray) -> dict[int, np.ndarray]:
    """Gradients (N, J, M, 7) as smooth_max_rows takes them: partials by state index."""
    return {i: grad[..., i] for i in range(NZ)}


def _ks(values: np.ndarray, width: np.ndarray) -> np.ndarray:
    top = np.max(values, axis=1, keepdims=True)
    return top[:, 0] + width * np.log(np.sum(np.exp((values - top) / width), axis=1))


def test_row_bounds_the_worst_sample_within_its_width() -> None:
    rng = np.random.default_rng(5)
    g = 0.01 * rng.normal(size=(N, J, M))
    width = np.array([0.002, 0.004])
    grads, samples = _dense(rng.normal(size=(N, J, M, NZ))), _samples(rng)
    rows = smooth_max_rows(g, grads, samples, width, exact=False)
    assert np.array_equal(rows.worst, np.max(g, axis=1))
    assert np.all(rows.g >= rows.worst)
    assert np.all(rows.g <= rows.worst + width * np.log(J) + 1e-15)


def test_coefficients_are_the_gradient_through_the_maps() -> None:
    rng = np.random.default_rng(6)
    g = 0.01 * rng.normal(size=(N, J, M))
    grad = rng.normal(size=(N, J, M, NZ))
    samples = _samples(rng)
    width = np.array([0.003, 0.003])
    rows = smooth_max_rows(g, _dense(grad), samples, width, exact=False)

    def row_value(dz: np.ndarray, dwm: float, dwp: float, ds: float) -> np.ndarray:
        dx = (
            np.einsum("njik,k->nji", samples.Phi, dz)
            + samples.Bm * dwm
            + samples.Bp * dwp
            + samples.S * ds
        )
        return _ks(g + np.einsum("njmi,nji->njm", grad, dx), width)

    h = 1e-7
    zero = np.zeros(NZ)
    for k in range(NZ):
        e = np.zeros(NZ)
        e[k] = h
        num = (row_value(e, 0, 0, 0) - row_value(-e, 0, 0, 0)) / (2 * h)
        # Central differences of a smooth function with h = 1e-7: error ~1e-9 relative.
        assert np.allclose(rows.c_z[:, :, k], num, rtol=1e-6, atol=1e-8)
    for field, args in (("c_wm", (h, 0, 0)), ("c_wp", (0, h, 0)), ("c_s", (0, 0, h))):
        plus = row_value(zero, *args)
        minus = row_value(zero, *(-a for a in args))
        assert np.allclose(getattr(rows, field), (plus - minus) / (2 * h), rtol=1e-6, atol=1e-8)


def test_narrow_width_gives_the_worst_sample_row() -> None:
    rng = np.random.default_rng(7)
    g = rng.normal(size=(N, J, M))  # well separated samples
    grad = rng.normal(size=(N, J, M, NZ))
    samples = _samples(rng)
    rows = smooth_max_rows(g, _dense(grad), samples, np.full(M, 1e-9), exact=False)
    worst = np.argmax(g, axis=1)
    for n in range(N):
        for m in range(M):
            j = worst[n, m]
            assert np.allclose(rows.c_z[n, m], grad[n, j, m] @ samples.Phi[n, j])
            assert np.isclose(rows.g[n, m], g[n, j, m])


def test_exact_row_is_the_worst_sample_with_the_smooth_gradient() -> None:
    """The exact row is the smooth maximum less its offset at the reference: its value is the
    worst sample bitwise (the offset d ln sum exp(...) removed), its coefficients the same
    smooth gradient as the conservative row's (bitwise: one kernel computes both)."""
    rng = np.random.default_rng(8)
    g = 0.01 * rng.normal(size=(N, J, M))
    grads, samples = _dense(rng.normal(size=(N, J, M, NZ))), _samples(rng)
    width = np.array([0.002, 0.004])
    exact = smooth_max_rows(g, grads, samples, width, exact=True)
    smooth = smooth_max_rows(g, grads, samples, width, exact=False)
    assert np.array_equal(exact.g, np.max(g, axis=1))
    assert np.array_equal(exact.worst, smooth.worst)
    assert np.array_equal(exact.c, smooth.c)
    assert np.all(smooth.g > exact.g)  # the conservative row's offset is strictly positive


def test_exact_row_holds_equal_samples_exactly() -> None:
    """With J equal samples the conservative row is above them by d ln J, its bound (the bias
    that grows as a mesh is refined); the exact row is on them."""
    rng = np.random.default_rng(9)
    g = np.repeat(0.01 * rng.normal(size=(N, 1, M)), J, axis=1)
    grads, samples = _dense(rng.normal(size=(N, J, M, NZ))), _samples(rng)
    width = np.array([0.002, 0.004])
    exact = smooth_max_rows(g, grads, samples, width, exact=True)
    smooth = smooth_max_rows(g, grads, samples, width, exact=False)
    assert np.array_equal(exact.g, g[:, 0])
    # ln of the sum of J ones in floating point: rounding of a few ulps of d ln J only.
    np.testing.assert_allclose(smooth.g - g[:, 0], np.tile(width * np.log(J), (N, 1)), rtol=1e-12)
