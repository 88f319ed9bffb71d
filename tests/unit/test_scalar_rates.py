"""The integrator's scalar right-hand side equals the vectorized dynamics (to round-off)."""

from __future__ import annotations

import numpy as np
import pytest

from worker.solver.aero_models import PolynomialAero
from worker.solver.alpha_schedules import VelocityScheduleAlpha
from worker.solver.atmosphere import ExponentialAtmosphere
from worker.solver.forces import VehicleForces
from worker.solver.models.point_mass import time_dynamics
from worker.solver.models.scalar_rates import time_rates
from worker.solver.units import Scales


@pytest.mark.parametrize("omega", [0.0, 0.0588])
def test_scalar_rates_match_vectorized_dynamics(omega: float) -> None:
    forces = VehicleForces(
        scales=Scales(6378140.0, 9.81),
        mass_kg=104305.0,
        area_m2=391.22,
        atmosphere=ExponentialAtmosphere(rho0=1.225, scale_height_m=7200.0),
        aero=PolynomialAero([-0.041065, 0.016292, 0.0002602], [0.080505, -0.03026, 0.86495], "cl"),
        alpha_schedule=VelocityScheduleAlpha(),
    )
    rng = np.random.default_rng(7)
    for _ in range(50):
        y = np.array([1.0 + rng.uniform(20e3, 100e3) / 6378140.0, rng.uniform(-1, 1),
                      rng.uniform(-1.2, 1.2), rng.uniform(0.15, 0.95), rng.uniform(-0.3, 0.1),
                      rng.uniform(-3, 3)])  # fmt: skip
        sigma = rng.uniform(-1.4, 1.4)
        u = np.array([[np.cos(sigma), np.sin(sigma)]])
        ref = time_dynamics(y[None, :], u, forces, omega, jacobians=False).f[0]
        _, lift, drag, _ = forces.lift_drag(y[0], y[3])
        fast = time_rates(y, float(u[0, 0]), float(u[0, 1]), float(lift), float(drag), omega)
        # the same formulas in another order of operations: equal to a few ulps of the largest term
        np.testing.assert_allclose(fast, ref, rtol=1e-12, atol=1e-14)
