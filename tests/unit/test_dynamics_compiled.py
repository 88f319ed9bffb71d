"""The compiled (numba) kernels against the numpy forms they replace, on the same inputs.

Both forms do the same arithmetic in double precision in a different order, so they agree to a
few ulps per operation; over 8 RK4 substeps that stays below 1e-12 of each quantity's scale
(tolerance 1e-11 relative), while any error in a formula shows at 1e-6 or far above. Hessian
blocks are forward differences with step 1e-5, which magnify the gradients' rounding by 1e5, so
they are compared to 1e-8 of their scale.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from app.schemas import ProblemDocument
from worker.solver.models.bank_state_compiled import compiled_parameters
from worker.solver.problem import EntryProblem, build_problem
from worker.solver.scenarios import get_scenario
from worker.solver.transcription.foh_exact import interval_maps, propagate_nodes
from worker.solver.transcription.foh_hessian import (
    BlockLayout,
    convexified_curvature,
    lagrangian_hessian,
)
from worker.solver.transcription.time_grid import initial_reference, propagate_constant_bank

Array = np.ndarray


def _problem(variant: str) -> EntryProblem:
    """Case 1 of paper 002, or a variant that takes the kernels' other branches."""
    raw = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    if variant == "no-rotation-constant-alpha":
        raw["planet"]["rotation"] = False
        raw["vehicle"]["angle_of_attack"] = {"mode": "constant", "alpha_deg": 25.0}
    elif variant == "cd-of-alpha":
        aero = raw["vehicle"]["aerodynamics"]
        aero["cd_argument"] = "alpha"
        aero["cd_coefficients"] = [0.07854, -0.0061592, 0.000621408]
    return build_problem(ProblemDocument.model_validate(raw))


def _reference(problem: EntryProblem) -> tuple[Array, Array, Array]:
    """A perturbed constant-bank reference with non-zero bank rates (40 nodes)."""
    ref = initial_reference(problem, 40, 20.0)
    rng = np.random.default_rng(7)
    z = ref.z + rng.normal(0.0, 1e-4, ref.z.shape)
    w = rng.normal(0.0, 0.02, ref.z.shape[0])
    return z, w, ref.s


def _close(a: Array, b: Array, rel: float) -> None:
    scale = max(float(np.max(np.abs(b))), 1e-300)
    assert float(np.max(np.abs(a - b))) <= rel * scale


VARIANTS = ("case-1", "no-rotation-constant-alpha", "cd-of-alpha")


@pytest.mark.parametrize("variant", VARIANTS)
def test_interval_maps_match_numpy(variant: str) -> None:
    p = _problem(variant)
    assert compiled_parameters(p.forces, p.omega) is not None
    z, w, s = _reference(p)
    args = (z[:-1], w[:-1], w[1:], s, p.forces, p.omega, 8, True)
    fast = interval_maps(*args)
    slow = interval_maps(*args, compiled=False)
    for name in ("x_prop", "Phi", "Bm", "Bp", "S"):
        _close(getattr(fast, name), getattr(slow, name), 1e-11)
    assert fast.samples is not None and slow.samples is not None
    _close(fast.samples.augmented, slow.samples.augmented, 1e-11)
    _close(
        propagate_nodes(z, w, s, p.forces, p.omega, 8),
        propagate_nodes(z, w, s, p.forces, p.omega, 8, compiled=False),
        1e-11,
    )


@pytest.mark.parametrize("with_interval", [True, False])
def test_hessian_blocks_match_numpy(with_interval: bool) -> None:
    p = _problem("case-1")
    z, w, s = _reference(p)
    weights = np.random.default_rng(3).normal(0.0, 1.0, (s.size, 7))
    nb = 10 if with_interval else 9
    steps = np.full(nb, 1e-5)
    fast = lagrangian_hessian(z, w, s, p.forces, p.omega, weights, steps, 2, with_interval)
    slow = lagrangian_hessian(
        z, w, s, p.forces, p.omega, weights, steps, 2, with_interval, compiled=False
    )
    assert fast is not None and slow is not None
    assert fast.shape == slow.shape == (s.size, nb, nb)
    _close(fast, slow, 1e-8)


@pytest.mark.parametrize("with_interval", [True, False])
def test_convexified_curvature_matches_numpy(with_interval: bool) -> None:
    """The subproblem's curvature entries (one compiled call: Hessian, scaling, eigenvalue
    clipping, upper triangles) against the numpy path; the blocks are compared to 1e-8 of their
    scale as above, and clipping them is Lipschitz with constant 1 in the Frobenius norm."""
    p = _problem("case-1")
    z, w, s = _reference(p)
    weights = np.random.default_rng(3).normal(0.0, 1.0, (s.size, 7))
    nb = 10 if with_interval else 9
    steps = np.full(nb, 1e-5)
    keep = np.array([j for j in range(nb) if j != 1], dtype=np.int64)
    upper = np.triu_indices(keep.size)
    layout = BlockLayout(keep, np.linspace(0.5, 2.0, keep.size), *upper)
    args = (z, w, s, p.forces, p.omega, weights, steps, 2, layout)
    fast = convexified_curvature(*args)
    slow = convexified_curvature(*args, compiled=False)
    assert fast is not None and slow is not None
    assert fast.shape == slow.shape == (s.size * upper[0].size,)
    _close(fast, slow, 1e-8)
    blocks = np.zeros((s.size, keep.size, keep.size))
    blocks[:, upper[0], upper[1]] = fast.reshape(s.size, -1)
    blocks[:, upper[1], upper[0]] = fast.reshape(s.size, -1)
    assert np.min(np.linalg.eigvalsh(blocks)) >= -1e-10 * np.max(np.abs(blocks))  # convex


def test_guess_sweep_matches_numpy_including_ground_impact() -> None:
    p = _problem("case-1")
    s = np.full(39, p.final_time / 39)  # type: ignore[operator]
    banks = np.radians([-80.0, 0.0, 20.0, 80.0])  # +-80 deg reach the ground: NaN from there on
    fast = propagate_constant_bank(p, banks, s)
    slow = propagate_constant_bank(p, banks, s, compiled=False)
    assert np.array_equal(np.isnan(fast), np.isnan(slow))
    assert np.isnan(fast[0, -1]).all() and np.isfinite(fast[2]).all()
    ok = np.isfinite(slow)
    _close(fast[ok], slow[ok], 1e-11)


def test_models_without_a_compiled_form_take_the_numpy_path() -> None:
    raw = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    raw["planet"]["atmosphere"] = {"model": "us76"}
    p = build_problem(ProblemDocument.model_validate(raw))
    assert compiled_parameters(p.forces, p.omega) is None
    z, w, s = _reference(p)
    maps = interval_maps(z[:-1], w[:-1], w[1:], s, p.forces, p.omega, 4)
    assert np.all(np.isfinite(maps.Phi))
