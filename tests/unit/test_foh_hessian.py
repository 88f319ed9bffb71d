"""Lagrangian curvature of the exact FOH interval maps (the SQP step of foh-ptr).

The Hessian blocks come from forward differences of the maps' Jacobians (sensitivity equations);
the independent check here differences the propagated end states themselves (central second
differences, no Jacobians), on a reference with unequal intervals and a sign-changing bank rate.
"""

from __future__ import annotations

import copy
import itertools

import numpy as np
import pytest

from app.schemas import ProblemDocument
from worker.solver.methods.foh_ptr.alpha_state import held_alpha, held_alpha_problem, with_alpha
from worker.solver.models.layout import BANK_STATE
from worker.solver.problem import EntryProblem, build_problem
from worker.solver.scenarios import get_scenario
from worker.solver.transcription.foh_exact import Dynamics, interval_maps
from worker.solver.transcription.foh_hessian import convexify, lagrangian_hessian
from worker.solver.transcription.foh_model import ALPHA_BANK_MODEL
from worker.solver.transcription.time_grid import initial_reference

SUBSTEPS = 2  # the method's default for the curvature integrations
NB = 10  # z_k (7), w_k, w_{k+1}, s_k


@pytest.fixture(scope="module")
def problem() -> EntryProblem:
    raw = dict(get_scenario("rlv-max-terminal-velocity").problem)
    return build_problem(ProblemDocument.model_validate(raw))


def _scales(problem: EntryProblem) -> np.ndarray:
    """The subproblem's units of z_k, w_k, w_{k+1}, s_k (1 km, 0.5 deg, ..., 1 deg/s, 10 s)."""
    rate = np.radians(1.0) * problem.scales.time_s
    return np.r_[BANK_STATE.trust_units(problem.scales), rate, rate, 10.0 / problem.scales.time_s]


def _reference(problem: EntryProblem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    ref = initial_reference(problem, 16, 20.0)
    s = ref.s * np.linspace(0.7, 1.3, ref.s.size)
    s *= ref.s.sum() / s.sum()
    w = np.radians(0.3) * problem.scales.time_s * np.cos(np.arange(16))
    return ref.z, w, s


def _second_differences(
    problem: EntryProblem,
    z: np.ndarray,
    w: np.ndarray,
    s: np.ndarray,
    weights: np.ndarray,
    h: np.ndarray,
    dynamics: Dynamics | None = None,
) -> np.ndarray:
    """d2 (weights_k . x_prop_k) / dv_i dv_j by central second differences of the end states;
    v_k = (z_k, w_k, w_{k+1}, s_k) with m = w.shape[1] rates per node for another ``dynamics``."""
    n, nz = s.size, z.shape[1]
    m = 1 if w.ndim == 1 else w.shape[1]
    nb = h.size
    pairs = list(itertools.product(range(nb), range(nb)))
    signs = [(1, 1), (1, -1), (-1, 1), (-1, -1)]
    dv = np.zeros((len(pairs), len(signs), n, nb))
    for q, (i, j) in enumerate(pairs):
        for c, (si, sj) in enumerate(signs):
            dv[q, c, :, i] += si * h[i]
            dv[q, c, :, j] += sj * h[j]
    dv = dv.reshape(-1, n, nb)
    copies = dv.shape[0]
    tiles = (copies,) if m == 1 else (copies, 1)
    rates = (lambda a: a.ravel()) if m == 1 else (lambda a: a.reshape(-1, m))
    x_end = interval_maps(
        np.tile(z[:-1], (copies, 1)) + dv[..., :nz].reshape(-1, nz),
        np.tile(w[:-1], tiles) + rates(dv[..., nz : nz + m]),
        np.tile(w[1:], tiles) + rates(dv[..., nz + m : nz + 2 * m]),
        np.tile(s, copies) + dv[..., -1].ravel(),
        problem.forces,
        problem.omega,
        SUBSTEPS,
        compiled=dynamics is None,
        dynamics=dynamics,
    ).x_prop.reshape(len(pairs), len(signs), n, nz)
    f = np.einsum("qcni,ni->qcn", x_end, weights)
    out = np.zeros((n, nb, nb))
    for q, (i, j) in enumerate(pairs):
        out[:, i, j] = (f[q, 0] - f[q, 1] - f[q, 2] + f[q, 3]) / (4.0 * h[i] * h[j])
    return out


def test_hessian_matches_second_differences_of_the_propagation(problem: EntryProblem) -> None:
    z, w, s = _reference(problem)
    weights = np.random.default_rng(1).normal(size=(s.size, 7))
    scale = _scales(problem)
    hess = lagrangian_hessian(
        z, w, s, problem.forces, problem.omega, weights, 1e-5 * scale, SUBSTEPS, True
    )
    assert hess is not None
    check = _second_differences(problem, z, w, s, weights, 1e-3 * scale)
    both = scale[None, :, None] * scale[None, None, :]  # compare in the subproblem's units
    a, b = hess * both, check * both
    # Forward differences of the Jacobians (step 1e-5) and central second differences of the
    # states (step 1e-3) each carry truncation errors near 1e-5 of a block's largest entry
    # (measured at most 4e-5); 1e-4 separates them from any real error (a sign or index slip
    # changes entries by their own size).
    err = np.max(np.abs(a - b), axis=(1, 2)) / np.max(np.abs(b), axis=(1, 2))
    assert np.all(err < 1e-4), err
    assert np.allclose(hess, np.transpose(hess, (0, 2, 1)))


def test_hessian_of_the_alpha_bank_model_matches_second_differences() -> None:
    """The same check on the model with the angle of attack as a second held state: 13 x 13
    blocks (z_k (8), both rates at both ends, s_k), numpy integrations on both sides."""
    raw = copy.deepcopy(get_scenario("shuttle-max-crossrange-heat-limited").problem)
    shuttle = build_problem(ProblemDocument.model_validate(raw))
    model = ALPHA_BANK_MODEL
    alpha = held_alpha(shuttle, model.unit)
    start = initial_reference(held_alpha_problem(shuttle, alpha, model.unit), 40, None)
    ref = with_alpha(start, alpha)
    z, s = ref.z[:4], ref.s[:3] * np.array([0.8, 1.0, 1.2])
    w = ref.w[:4].copy()
    w[:, 0] = np.radians(0.3) * shuttle.scales.time_s * np.cos(np.arange(4))
    w[:, 1] = np.radians(0.05) * shuttle.scales.time_s * np.sin(np.arange(4))
    weights = np.random.default_rng(3).normal(size=(s.size, 8))
    rate = np.radians(1.0) * shuttle.scales.time_s
    units = model.layout.trust_units(shuttle.scales)
    scale = np.r_[units, [rate] * 4, 10.0 / shuttle.scales.time_s]
    hess = lagrangian_hessian(
        z, w, s, shuttle.forces, shuttle.omega, weights, 1e-5 * scale, SUBSTEPS, True,
        compiled=False, dynamics=model.dynamics,
    )  # fmt: skip
    assert hess is not None and hess.shape == (s.size, 13, 13)
    check = _second_differences(shuttle, z, w, s, weights, 1e-3 * scale, model.dynamics)
    both = scale[None, :, None] * scale[None, None, :]
    err = np.max(np.abs((hess - check) * both), axis=(1, 2)) / np.max(np.abs(check * both))
    assert np.all(err < 1e-4), err  # the truncation errors of the two differences, as above


def test_hessian_without_interval_variable_is_the_leading_block(problem: EntryProblem) -> None:
    z, w, s = _reference(problem)
    weights = np.random.default_rng(2).normal(size=(s.size, 7))
    steps = 1e-5 * _scales(problem)
    full = lagrangian_hessian(z, w, s, problem.forces, problem.omega, weights, steps, 2, True)
    fixed = lagrangian_hessian(z, w, s, problem.forces, problem.omega, weights, steps[:9], 2, False)
    assert full is not None and fixed is not None
    # Same integrations, same differences: equal to rounding.
    assert np.allclose(fixed, full[:, :9, :9], rtol=1e-12, atol=0.0)


def test_hessian_of_a_non_finite_reference_is_none(problem: EntryProblem) -> None:
    z, w, s = _reference(problem)
    z = z.copy()
    z[3, 0] = np.nan
    steps = 1e-5 * _scales(problem)
    weights = np.ones((s.size, 7))
    assert (
        lagrangian_hessian(z, w, s, problem.forces, problem.omega, weights, steps, 2, True) is None
    )


def test_convexify_clips_negative_curvature_and_keeps_convex_blocks() -> None:
    rng = np.random.default_rng(3)
    a = rng.normal(size=(20, 6, 6))
    blocks = a + np.transpose(a, (0, 2, 1))  # symmetric, indefinite
    out = convexify(blocks)
    assert np.all(np.linalg.eigvalsh(out) >= -1e-12)
    psd = np.einsum("kij,klj->kil", a, a)  # a a' is positive semidefinite
    # Unchanged up to the eigendecomposition's rounding (entries of order 10).
    assert np.allclose(convexify(psd), psd, rtol=0.0, atol=1e-10)
    lam, vec = np.linalg.eigh(blocks[0])
    expected = vec @ np.diag(np.maximum(lam, 0.0)) @ vec.T
    assert np.allclose(out[0], expected, rtol=0.0, atol=1e-10)
