"""The powered point-mass equations (paper 004's skip entry with thrust) against an independent
SI transcription of the standard equations, and their reduction to the unpowered model."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from app.schemas import ProblemDocument
from worker.solver.models.point_mass import time_dynamics
from worker.solver.models.powered import G_STANDARD, PoweredModel, powered_path_values
from worker.solver.phased_problem import build_phased_problem

SCENARIOS = Path(__file__).resolve().parents[2] / "worker" / "solver" / "scenarios"
# the two sides compute the same expressions in different units and orders: 1e-12 relative is
# a few hundred machine epsilons
RTOL = 1e-12


def _skip() -> ProblemDocument:
    doc = json.loads((SCENARIOS / "shuttle-skip-min-propellant.json").read_text())["problem"]
    return ProblemDocument.model_validate(doc)


def _states(n: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(4)
    x = np.column_stack(
        [
            1.0 + rng.uniform(30e3, 90e3, n) / 6371203.92,
            rng.uniform(-1, 1, n),
            rng.uniform(-1.2, 1.2, n),
            rng.uniform(0.2, 0.95, n),
            rng.uniform(-0.2, 0.2, n),
            rng.uniform(0, 6, n),
            rng.uniform(0.3, 1.0, n),
            rng.uniform(0.0, 2.0, n),
        ]
    )
    u = np.column_stack(
        [rng.uniform(-0.5, 1.5, n), rng.uniform(-1.5, 1.5, n), rng.uniform(0, 2, n)]
    )
    return x, u


def test_the_rates_match_an_independent_si_transcription() -> None:
    pb = build_phased_problem(_skip())
    model, sc, m0 = pb.model, pb.base.scales, pb.mass_kg
    assert model.thruster is not None and model.omega == 0.0
    x, u = _states(25)
    f = model.rates(x, u)
    # SI: the standard point-mass equations over a non-rotating sphere, thrust along the body
    # axis at alpha, banked with the lift
    R, g0 = sc.radius_m, sc.g0_m_s2
    r = x[:, 0] * R
    lat, v, gam, psi = x[:, 2], x[:, 3] * sc.speed_m_s, x[:, 4], x[:, 5]
    m, thrust = x[:, 6] * m0, x[:, 7] * m0 * g0
    alpha, sigma, command = u[:, 0], u[:, 1], u[:, 2] * m0 * g0
    rho, _ = pb.base.forces.atmosphere.density(r - R)
    a = np.degrees(alpha)
    cl = -0.20704 + 0.029244 * a
    cd = 0.07854 - 0.61592e-2 * a + 0.621408e-3 * a * a
    q = 0.5 * rho * v * v * pb.base.forces.area_m2
    lift, drag = q * cl, q * cd
    g = g0 * R * R / (r * r)
    normal = lift + thrust * np.sin(alpha)
    expected = np.column_stack(
        [
            v * np.sin(gam),
            v * np.cos(gam) * np.sin(psi) / (r * np.cos(lat)),
            v * np.cos(gam) * np.cos(psi) / r,
            (thrust * np.cos(alpha) - drag) / m - g * np.sin(gam),
            normal * np.cos(sigma) / (m * v) - (g / v - v / r) * np.cos(gam),
            normal * np.sin(sigma) / (m * v * np.cos(gam))
            + v * np.cos(gam) * np.sin(psi) * np.tan(lat) / r,
            -thrust / (316.0 * G_STANDARD),
            (command - thrust) / 1.0,
        ]
    )
    per_unit = (
        np.array([R, 1.0, 1.0, g0, 1.0, 1.0, m0, m0 * g0], dtype=float) / sc.time_s
    )  # SI rate of one nondimensional state unit per nondimensional time unit
    per_unit[3] = g0  # speed: (m/s) / s = g0 per unit
    assert np.allclose(f * per_unit, expected, rtol=RTOL, atol=0.0)


def test_without_thrust_and_at_the_initial_mass_it_is_the_unpowered_model() -> None:
    pb = build_phased_problem(_skip())
    x, u = _states(12)
    x[:, 6], x[:, 7], u[:, 2] = 1.0, 0.0, 0.0
    f = pb.model.rates(x, u)
    sigma = u[:, 1]
    plain = time_dynamics(
        x[:, :6], np.column_stack([np.cos(sigma), np.sin(sigma)]), pb.base.forces, 0.0,
        np.degrees(u[:, 0]), jacobians=False,
    ).f  # fmt: skip
    assert np.allclose(f[:, :6], plain, rtol=RTOL, atol=1e-15)
    assert np.all(f[:, 6:] == 0.0)


def test_an_unpowered_model_keeps_six_states_and_two_controls() -> None:
    pb = build_phased_problem(_skip())
    bare = PoweredModel(pb.model.forces, 0.0, None)
    assert (bare.n_states, bare.n_controls) == (6, 2)
    x, u = _states(3)
    assert bare.rates(x[:, :6], u[:, :2]).shape == (3, 6)


def test_the_load_factor_is_aerodynamic_over_the_current_mass() -> None:
    pb = build_phased_problem(_skip())
    x, u = _states(6)
    light = x.copy()
    light[:, 6] = 0.5 * x[:, 6]
    heavy = powered_path_values(pb.model, pb.phases[0].limits, x, u)
    half = powered_path_values(pb.model, pb.phases[0].limits, light, u)
    assert np.allclose(half.load_factor, 2.0 * heavy.load_factor, rtol=RTOL)
    assert np.array_equal(half.heat_rate, heavy.heat_rate)  # thrust and mass do not heat


def test_the_thruster_units_follow_the_document() -> None:
    pb = build_phased_problem(_skip())
    thr, sc = pb.model.thruster, pb.base.scales
    assert thr is not None and thr.lag_rate is not None
    assert math.isclose(thr.max_thrust * pb.thrust_unit_n, 2.0e6, rel_tol=RTOL)
    assert math.isclose(sc.time_s / thr.lag_rate, 1.0, rel_tol=RTOL)
    assert thr.dry_mass is not None and math.isclose(thr.dry_mass, 0.2, rel_tol=RTOL)
    assert [p.name for p in pb.phases] == ["descent", "exit"]
    assert pb.phases[0].thrust_max == 0.0 and pb.phases[1].thrust_max == thr.max_thrust
