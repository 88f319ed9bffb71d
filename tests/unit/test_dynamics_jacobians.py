"""Analytic Jacobians of the time- and energy-form dynamics against the complex-step method.

Complex step: f'(x) ~ Im f(x + i h) / h has no subtractive cancellation, so with h = 1e-30 it is
exact to machine precision; the analytic Jacobians must match it to 1e-8 relative (issue
acceptance), far looser than the ~1e-15 the comparison can resolve.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.unit.corridor import corridor_states
from worker.solver.aero_models import PolynomialAero
from worker.solver.alpha_schedules import VelocityScheduleAlpha
from worker.solver.atmosphere import ExponentialAtmosphere
from worker.solver.forces import VehicleForces
from worker.solver.models.point_mass import energy_dynamics, time_dynamics
from worker.solver.units import Scales

STEP = 1e-30
RTOL = 1e-8


def _forces() -> VehicleForces:
    return VehicleForces(
        scales=Scales(6378140.0, 9.81),
        mass_kg=104305.0,
        area_m2=391.22,
        atmosphere=ExponentialAtmosphere(rho0=1.225, scale_height_m=7200.0),
        aero=PolynomialAero([-0.041065, 0.016292, 0.0002602], [0.080505, -0.03026, 0.86495], "cl"),
        alpha_schedule=VelocityScheduleAlpha(),
    )


def _states(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Time-form states spread over the entry corridor; speeds on both sides of the alpha break."""
    y = corridor_states(n, rng)
    sigma = rng.uniform(-1.4, 1.4, n)
    u = np.column_stack([np.cos(sigma), np.sin(sigma)]) * rng.uniform(0.8, 1.0, n)[:, None]
    return y, u


def _assert_close(analytic: np.ndarray, numeric: np.ndarray) -> None:
    """Relative error per entry; entries below 1e-6 of the node's largest (and below 1e-6 in
    absolute terms: the quantities are O(1) nondimensional) are compared absolutely, since at
    that size cancellation round-off (~1e-17) is all they contain."""
    axes = tuple(range(1, numeric.ndim))
    node_max = np.max(np.abs(numeric), axis=axes, keepdims=True) if axes else np.abs(numeric)
    scale = np.maximum(np.abs(numeric), 1e-6 * np.maximum(1.0, node_max))
    err = np.max(np.abs(analytic - numeric) / scale)
    assert err <= RTOL, f"largest relative error {err:.3e}"


@pytest.mark.parametrize("omega", [0.0, 0.0588])
def test_time_dynamics_jacobians(omega: float) -> None:
    rng = np.random.default_rng(1)
    forces = _forces()
    y, u = _states(64, rng)
    ref = time_dynamics(y, u, forces, omega)
    num_a = np.zeros_like(ref.A)
    for k in range(6):
        yc = y.astype(complex)
        yc[:, k] += 1j * STEP
        num_a[:, :, k] = time_dynamics(yc, u, forces, omega).f.imag / STEP
    num_b = np.zeros_like(ref.B)
    for k in range(2):
        uc = u.astype(complex)
        uc[:, k] += 1j * STEP
        num_b[:, :, k] = time_dynamics(y, uc, forces, omega).f.imag / STEP
    _assert_close(ref.A, num_a)
    _assert_close(ref.B, num_b)


@pytest.mark.parametrize("omega", [0.0, 0.0588])
def test_energy_dynamics_jacobians(omega: float) -> None:
    rng = np.random.default_rng(2)
    forces = _forces()
    y, u = _states(64, rng)
    x = y[:, [0, 1, 2, 4, 5]]
    e = 1.0 / y[:, 0] - 0.5 * y[:, 3] ** 2
    ref = energy_dynamics(x, u, e, forces, omega)
    num_a = np.zeros_like(ref.A)
    num_edot = np.zeros_like(ref.edot_x)
    for k in range(5):
        xc = x.astype(complex)
        xc[:, k] += 1j * STEP
        out = energy_dynamics(xc, u, e, forces, omega)
        num_a[:, :, k] = out.f.imag / STEP
        num_edot[:, k] = out.edot.imag / STEP
    num_b = np.zeros_like(ref.B)
    for k in range(2):
        uc = u.astype(complex)
        uc[:, k] += 1j * STEP
        num_b[:, :, k] = energy_dynamics(x, uc, e, forces, omega).f.imag / STEP
    _assert_close(ref.A, num_a)
    _assert_close(ref.edot_x, num_edot)
    _assert_close(ref.B, num_b)


def test_energy_rate_equals_drag_times_speed_without_rotation() -> None:
    """de/dt = D V exactly on a non-rotating planet (paper 000, below eq. 7)."""
    rng = np.random.default_rng(3)
    forces = _forces()
    y, u = _states(16, rng)
    x = y[:, [0, 1, 2, 4, 5]]
    e = 1.0 / y[:, 0] - 0.5 * y[:, 3] ** 2
    out = energy_dynamics(x, u, e, forces, 0.0)
    np.testing.assert_allclose(out.edot, out.time.forces.drag * y[:, 3], rtol=1e-13)
