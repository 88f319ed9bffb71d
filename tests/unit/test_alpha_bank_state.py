"""The 8-state model (angle of attack and bank as states): complex-step Jacobians and agreement
with the bank-state model when alpha is held on its schedule, with and without rotation.

Complex step: f'(x) ~ Im f(x + i h) / h has no subtractive cancellation, so with h = 1e-30 it is
exact to machine precision; the analytic A and B must match it to 1e-8 relative (the issue's
acceptance for the other models), far looser than the ~1e-15 the comparison resolves and far
tighter than any formula error (1e-3 or more). Against the bank-state model the rates differ only
by alpha's degree -> radian -> degree round trip (a few ulps), so they agree to 1e-13 relative.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.unit.corridor import corridor_states
from worker.solver.aero_models import PolynomialAero
from worker.solver.alpha_schedules import ConstantAlpha, VelocityScheduleAlpha
from worker.solver.atmosphere import ExponentialAtmosphere
from worker.solver.forces import VehicleForces
from worker.solver.models.alpha_bank_state import ALPHA, alpha_bank_state_dynamics
from worker.solver.models.bank_state import bank_state_dynamics
from worker.solver.models.layout import ALPHA_BANK_STATE, BANK_STATE
from worker.solver.units import Scales

STEP = 1e-30
RTOL = 1e-8
OMEGAS = [0.0, 0.0588]  # non-rotating, and Earth's rate in units of sqrt(g0 / R0)


def _forces(schedule: VelocityScheduleAlpha | ConstantAlpha | None = None) -> VehicleForces:
    return VehicleForces(
        scales=Scales(6378140.0, 9.81),
        mass_kg=104305.0,
        area_m2=391.22,
        atmosphere=ExponentialAtmosphere(rho0=1.225, scale_height_m=7200.0),
        aero=PolynomialAero([-0.041065, 0.016292, 0.0002602], [0.080505, -0.03026, 0.86495], "cl"),
        alpha_schedule=schedule,
    )


def _states(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """8-states over the entry corridor, rates of bank and alpha, and interval lengths."""
    y = corridor_states(n, rng)
    sigma = rng.uniform(-1.4, 1.4, n)
    alpha = np.radians(rng.uniform(5.0, 45.0, n))
    z = np.column_stack([y, sigma, alpha])
    w = rng.normal(0.0, 0.05, (n, 2))
    return z, w, rng.uniform(0.005, 0.05, n)


def _assert_close(analytic: np.ndarray, numeric: np.ndarray, rtol: float) -> None:
    """Relative error per entry; entries below 1e-6 of the node's largest are compared
    absolutely at that scale (they hold only cancellation round-off)."""
    axes = tuple(range(1, numeric.ndim))
    node_max = np.max(np.abs(numeric), axis=axes, keepdims=True)
    scale = np.maximum(np.abs(numeric), 1e-6 * np.maximum(1.0, node_max))
    err = float(np.max(np.abs(analytic - numeric) / scale))
    assert err <= rtol, f"largest relative error {err:.3e}"


def test_layout_sizes() -> None:
    assert ALPHA_BANK_STATE.size == 8
    assert ALPHA == ALPHA_BANK_STATE.index("angle_of_attack_deg") == 7


@pytest.mark.parametrize("omega", OMEGAS)
def test_jacobians_match_complex_step(omega: float) -> None:
    rng = np.random.default_rng(3)
    forces = _forces()
    z, w, s = _states(48, rng)
    ref = alpha_bank_state_dynamics(z, w, forces, omega, s)
    assert ref.A is not None and ref.B is not None
    assert ref.A.shape == (48, 8, 8) and ref.B.shape == (48, 8, 2)
    num_a = np.zeros_like(ref.A)
    for k in range(8):
        zc = z.astype(complex)
        zc[:, k] += 1j * STEP
        num_a[:, :, k] = alpha_bank_state_dynamics(zc, w, forces, omega, s).F.imag / STEP
    num_b = np.zeros_like(ref.B)
    for k in range(2):
        wc = w.astype(complex)
        wc[:, k] += 1j * STEP
        num_b[:, :, k] = alpha_bank_state_dynamics(z, wc, forces, omega, s).F.imag / STEP
    _assert_close(ref.A, num_a, RTOL)
    _assert_close(ref.B, num_b, RTOL)
    np.testing.assert_array_equal(ref.F, s[:, None] * ref.S)
    np.testing.assert_array_equal(ref.S[:, 6:], w)
    assert not np.any(ref.A[:, :, 1])  # no rate depends on the longitude


@pytest.mark.parametrize("omega", OMEGAS)
@pytest.mark.parametrize("schedule", [VelocityScheduleAlpha(), ConstantAlpha(25.0)])
def test_matches_bank_state_on_the_schedule(
    omega: float, schedule: VelocityScheduleAlpha | ConstantAlpha
) -> None:
    rng = np.random.default_rng(5)
    forces = _forces(schedule)
    z, w, s = _states(40, rng)
    alpha_deg, _ = schedule.alpha_deg(z[:, 3] * forces.scales.speed_m_s)
    z[:, ALPHA] = np.radians(alpha_deg)
    eight = alpha_bank_state_dynamics(z, w, forces, omega, s)
    seven = bank_state_dynamics(z[:, : BANK_STATE.size], w[:, 0], forces, omega, s)
    _assert_close(eight.F[:, :7], seven.F, 1e-13)
    assert eight.A is not None and seven.A is not None
    if isinstance(schedule, ConstantAlpha):  # no schedule slope: the 7 x 7 blocks agree too
        _assert_close(eight.A[:, :7, :7], seven.A, 1e-12)
    else:  # only the speed column carries the schedule's slope
        others = [j for j in range(7) if j != 3]
        _assert_close(eight.A[:, :7, others], seven.A[:, :, others], 1e-12)


def test_alpha_is_in_radians() -> None:
    """One degree of alpha moves the lift as the aerodynamic model's slope per degree says."""
    forces = _forces()
    z, w, _ = _states(4, np.random.default_rng(9))
    d = alpha_bank_state_dynamics(z, w, forces, 0.0)
    assert d.A is not None
    np.testing.assert_allclose(d.A[:, 3, ALPHA] * math.radians(1.0), -d.forces.drag_a, rtol=1e-14)
