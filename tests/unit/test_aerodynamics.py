"""Aerodynamic models and alpha schedules: paper values, derivatives, clamping, builders."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from worker.solver.aero_models import AeroModel, ParabolicPolarAero, PolynomialAero
from worker.solver.aero_tables import TableAero
from worker.solver.aerodynamics import aero_from_spec, alpha_schedule_from_spec
from worker.solver.alpha_schedules import (
    AlphaSchedule,
    ConstantAlpha,
    TableAlpha,
    VelocityScheduleAlpha,
)

STEP = 1e-30  # complex step: no subtractive cancellation, so the step can be tiny
CS_RTOL = 1e-10  # complex step is exact to rounding; 1e-10 leaves room for a few operations
EXACT_RTOL = 1e-12  # a few roundings of double-precision arithmetic on O(1) numbers

LU_CL = [-0.041065, 0.016292, 0.0002602]
LU_CD = [0.080505, -0.03026, 0.86495]
SHUTTLE_CL = [-0.20704, 0.029244]
SHUTTLE_CD = [0.07854, -0.61592e-2, 0.621408e-3]


def test_lu_polynomial_at_40_deg() -> None:
    c = PolynomialAero(LU_CL, LU_CD, "cl").coefficients(np.array([40.0]), np.array([20.0]))
    # references worked out in exact decimal arithmetic
    assert c.cl[0] == pytest.approx(1.026935, rel=EXACT_RTOL)
    assert c.cd[0] == pytest.approx(0.96160231962991375, rel=EXACT_RTOL)
    assert c.dcl_dalpha[0] == pytest.approx(0.016292 + 2 * 0.0002602 * 40, rel=EXACT_RTOL)


def test_shuttle_polynomial_at_40_deg() -> None:
    c = PolynomialAero(SHUTTLE_CL, SHUTTLE_CD, "alpha").coefficients(40.0, 25.0)
    assert c.cl == pytest.approx(0.96272, rel=EXACT_RTOL)
    assert c.cd == pytest.approx(0.8264248, rel=EXACT_RTOL)


@pytest.mark.parametrize(
    ("cl", "cd", "arg"), [(LU_CL, LU_CD, "cl"), (SHUTTLE_CL, SHUTTLE_CD, "alpha")]
)
def test_polynomial_derivatives_complex_step(cl: list[float], cd: list[float], arg: str) -> None:
    model = PolynomialAero(cl, cd, arg)  # type: ignore[arg-type]
    alpha = np.linspace(-5.0, 45.0, 41)
    mach = np.full(alpha.shape, 12.0)
    c = model.coefficients(alpha, mach)
    cc = model.coefficients(alpha + 1j * STEP, mach)
    np.testing.assert_allclose(c.dcl_dalpha, cc.cl.imag / STEP, rtol=CS_RTOL)
    np.testing.assert_allclose(c.dcd_dalpha, cc.cd.imag / STEP, rtol=CS_RTOL)
    cm = model.coefficients(alpha, mach + 1j * STEP)
    assert np.all(cm.cl.imag == 0.0) and np.all(c.dcl_dmach == 0.0) and np.all(c.dcd_dmach == 0.0)


def test_polynomial_broadcasts_and_validates() -> None:
    c = PolynomialAero(LU_CL, LU_CD, "cl").coefficients(np.zeros(3), np.zeros((2, 1)))
    assert c.cl.shape == c.dcd_dmach.shape == (2, 3)
    with pytest.raises(ValueError, match="cd_argument"):
        PolynomialAero(LU_CL, LU_CD, "mach")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="cl_coefficients"):
        PolynomialAero([], LU_CD, "cl")


def test_parabolic_polar() -> None:
    cd0, k = 0.046, 0.8
    model = ParabolicPolarAero(cl_star=float(np.sqrt(cd0 / k)), cd0=cd0, k_induced=k)
    lam = np.linspace(0.1, 2.0, 191)
    cl, cd, dcl, dcd = model.polar(lam)
    assert lam[np.argmax(cl / cd)] == pytest.approx(1.0)  # cl_star is the max-L/D point
    clc, cdc, _, _ = model.polar(lam + 1j * STEP)
    np.testing.assert_allclose(dcl, clc.imag / STEP, rtol=CS_RTOL)
    np.testing.assert_allclose(dcd, cdc.imag / STEP, rtol=CS_RTOL)
    # the lift control lam takes the angle of attack's place; at lam = 1, cd0 + k cl*^2 = 2 cd0
    c = model.coefficients(np.array([1.0, 0.5]), np.array([3.0, 20.0]))
    np.testing.assert_allclose(c.cl, [model.cl_star, 0.5 * model.cl_star], rtol=EXACT_RTOL)
    np.testing.assert_allclose(c.cd, [2 * cd0, 1.25 * cd0], rtol=EXACT_RTOL)
    np.testing.assert_allclose(c.dcl_dalpha, model.cl_star, rtol=EXACT_RTOL)
    np.testing.assert_allclose(c.dcd_dalpha, [2 * cd0 / 1.0, cd0], rtol=EXACT_RTOL)
    assert np.all(c.dcd_dmach == 0.0)
    with pytest.raises(ValueError, match="cd0"):
        ParabolicPolarAero(cl_star=0.3, cd0=0.0, k_induced=1.0)


def _poly_table(
    na: int, nm: int, f: object
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Grid with unequal spacing, CL = ``f`` tabulated on it and CD = 0.5 + 0.1 CL."""
    a = np.linspace(-10.0, 50.0, na) + np.sin(np.arange(na))  # uneven steps
    m = np.linspace(1.0, 25.0, nm) ** 1.1
    cl = f(a[:, None], m[None, :])  # type: ignore[operator]
    return a, m, cl, 0.5 + 0.1 * cl


def _bilinear(a: np.ndarray, m: np.ndarray) -> np.ndarray:
    return 0.3 + 0.02 * a - 0.01 * m + 0.001 * a * m


def test_linear_table_reproduces_bilinear_function() -> None:
    a, m, cl, cd = _poly_table(5, 4, _bilinear)
    model = TableAero(a, m, cl, cd, "linear")
    rng = np.random.default_rng(0)
    aq, mq = rng.uniform(a[0], a[-1], 50), rng.uniform(m[0], m[-1], 50)
    c = model.coefficients(aq, mq)
    # bilinear interpolation is exact for a bilinear function, up to rounding
    np.testing.assert_allclose(c.cl, _bilinear(aq, mq), rtol=EXACT_RTOL)
    np.testing.assert_allclose(c.dcl_dalpha, 0.02 + 0.001 * mq, rtol=1e-10)
    np.testing.assert_allclose(c.dcl_dmach, -0.01 + 0.001 * aq, rtol=1e-10, atol=1e-14)


@pytest.mark.parametrize(("na", "nm", "pa", "pm"), [(5, 6, 3, 3), (2, 3, 1, 2), (3, 2, 2, 1)])
def test_cubic_table_reproduces_polynomials(na: int, nm: int, pa: int, pm: int) -> None:
    """A tensor spline of degree min(3, n-1) per axis reproduces polynomials of that degree."""

    def f(a: np.ndarray, m: np.ndarray) -> np.ndarray:
        return (1 + 0.01 * a + 1e-4 * a**pa) * (2 - 0.05 * m + 1e-3 * m**pm)

    def f_a(a: np.ndarray, m: np.ndarray) -> np.ndarray:
        return (0.01 + pa * 1e-4 * a ** (pa - 1)) * (2 - 0.05 * m + 1e-3 * m**pm)

    def f_m(a: np.ndarray, m: np.ndarray) -> np.ndarray:
        return (1 + 0.01 * a + 1e-4 * a**pa) * (-0.05 + pm * 1e-3 * m ** (pm - 1))

    a, m, cl, cd = _poly_table(na, nm, f)
    model = TableAero(a, m, cl, cd, "cubic")
    rng = np.random.default_rng(1)
    aq, mq = rng.uniform(a[0], a[-1], 40), rng.uniform(m[0], m[-1], 40)
    c = model.coefficients(aq, mq)
    # exact reproduction; 1e-9 allows for the conditioning of the spline fit
    np.testing.assert_allclose(c.cl, f(aq, mq), rtol=1e-9)
    np.testing.assert_allclose(c.dcl_dalpha, f_a(aq, mq), rtol=1e-9)
    np.testing.assert_allclose(c.dcl_dmach, f_m(aq, mq), rtol=1e-9)
    np.testing.assert_allclose(c.dcd_dalpha, 0.1 * f_a(aq, mq), rtol=1e-9)


@pytest.mark.parametrize("interpolation", ["linear", "cubic"])
def test_table_derivatives_finite_difference(interpolation: str) -> None:
    rng = np.random.default_rng(2)
    a = np.array([0.0, 10.0, 20.0, 30.0, 45.0])
    m = np.array([2.0, 5.0, 10.0, 20.0])
    model = TableAero(a, m, rng.random((5, 4)), rng.random((5, 4)), interpolation)  # type: ignore[arg-type]
    # mid-cell points so that the linear model's stencil stays inside one cell
    aq = np.array([5.0, 13.0, 27.0, 40.0, 2.5])
    mq = np.array([3.0, 7.0, 15.0, 4.0, 12.0])
    h = 1e-5
    c = model.coefficients(aq, mq)
    for attr in ("cl", "cd"):
        fd_a = (
            getattr(model.coefficients(aq + h, mq), attr)
            - getattr(model.coefficients(aq - h, mq), attr)
        ) / (2 * h)
        fd_m = (
            getattr(model.coefficients(aq, mq + h), attr)
            - getattr(model.coefficients(aq, mq - h), attr)
        ) / (2 * h)
        # truncation h^2 f'''/6 ~ 1e-12 for these O(1) tables; rounding eps/h ~ 1e-11
        np.testing.assert_allclose(getattr(c, f"d{attr}_dalpha"), fd_a, rtol=0, atol=1e-9)
        np.testing.assert_allclose(getattr(c, f"d{attr}_dmach"), fd_m, rtol=0, atol=1e-9)


@pytest.mark.parametrize("interpolation", ["linear", "cubic"])
def test_table_complex_input_is_first_order_taylor(interpolation: str) -> None:
    rng = np.random.default_rng(3)
    a, m = np.array([0.0, 15.0, 30.0, 45.0]), np.array([2.0, 6.0, 12.0])
    model = TableAero(a, m, rng.random((4, 3)), rng.random((4, 3)), interpolation)  # type: ignore[arg-type]
    aq, mq = np.array([7.0, 33.0, -5.0]), np.array([4.0, 10.0, 8.0])
    c = model.coefficients(aq, mq)
    ca = model.coefficients(aq + 1j * STEP, mq)
    cm = model.coefficients(aq, mq + 1j * STEP)
    np.testing.assert_allclose(ca.cl.imag / STEP, c.dcl_dalpha, rtol=CS_RTOL, atol=1e-300)
    np.testing.assert_allclose(cm.cd.imag / STEP, c.dcd_dmach, rtol=CS_RTOL, atol=1e-300)
    # the partials' imaginary parts carry the second partials: compare with central differences
    # of the partials (the linear stencils stay inside one cell; the mach axis has 3 points, so
    # the cubic model's d2/dmach2 comes from the divided-difference path)
    h = 1e-5
    a_hi, a_lo = model.coefficients(aq + h, mq), model.coefficients(aq - h, mq)
    m_hi, m_lo = model.coefficients(aq, mq + h), model.coefficients(aq, mq - h)
    # truncation h^2 f''''/6 is negligible; rounding eps * |f'| / h ~ 1e-12
    for numeric, analytic in [
        (a_hi.dcl_dalpha - a_lo.dcl_dalpha, ca.dcl_dalpha),
        (a_hi.dcl_dmach - a_lo.dcl_dmach, ca.dcl_dmach),
        (m_hi.dcl_dmach - m_lo.dcl_dmach, cm.dcl_dmach),
        (m_hi.dcl_dalpha - m_lo.dcl_dalpha, cm.dcl_dalpha),
    ]:
        np.testing.assert_allclose(analytic.imag / STEP, numeric / (2 * h), rtol=0, atol=1e-9)


@pytest.mark.parametrize("interpolation", ["linear", "cubic"])
def test_table_clamps_outside(interpolation: str) -> None:
    rng = np.random.default_rng(4)
    a, m = np.array([0.0, 20.0, 40.0]), np.array([2.0, 10.0])
    model = TableAero(a, m, rng.random((3, 2)), rng.random((3, 2)), interpolation)  # type: ignore[arg-type]
    out = model.coefficients(np.array([-10.0, 60.0, 20.0]), np.array([5.0, 50.0, 1.0]))
    edge = model.coefficients(np.array([0.0, 40.0, 20.0]), np.array([5.0, 10.0, 2.0]))
    np.testing.assert_allclose(out.cl, edge.cl, rtol=EXACT_RTOL)
    assert out.dcl_dalpha[0] == 0.0 and out.dcl_dalpha[1] == 0.0 and out.dcl_dalpha[2] != 0.0
    assert out.dcd_dmach[0] != 0.0 and out.dcd_dmach[1] == 0.0 and out.dcd_dmach[2] == 0.0


def test_table_validation() -> None:
    with pytest.raises(ValueError, match="shape"):
        TableAero([0.0, 10.0], [1.0, 2.0], [[1.0, 2.0]], [[1.0, 2.0], [3.0, 4.0]])
    with pytest.raises(ValueError, match="strictly increasing"):
        TableAero([0.0, 0.0], [1.0, 2.0], np.ones((2, 2)), np.ones((2, 2)))
    with pytest.raises(ValueError, match="interpolation"):
        TableAero([0.0, 1.0], [1.0, 2.0], np.ones((2, 2)), np.ones((2, 2)), "spline")  # type: ignore[arg-type]


def test_velocity_schedule_paper_values() -> None:
    alpha, dalpha = VelocityScheduleAlpha().alpha_deg(np.array([3000.0, 4570.0, 6000.0]))
    # references worked out in exact decimal arithmetic
    np.testing.assert_allclose(alpha, [35.585142344290657, 40.0, 40.0], rtol=EXACT_RTOL)
    np.testing.assert_allclose(dalpha, [0.0056240224913494810, 0.0, 0.0], rtol=EXACT_RTOL)


def test_velocity_schedule_complex_step_and_continuity() -> None:
    schedule = VelocityScheduleAlpha(alpha_max_deg=35.0, velocity_break_m_s=4000.0)
    v = np.linspace(1000.0, 7000.0, 61) + 3.3  # both branches, no point on the break
    _, dalpha = schedule.alpha_deg(v)
    alpha_c, _ = schedule.alpha_deg(v + 1j * STEP)
    np.testing.assert_allclose(dalpha, alpha_c.imag / STEP, rtol=CS_RTOL, atol=1e-300)
    near, dnear = schedule.alpha_deg(np.array([4000.0 - 1e-6, 4000.0 + 1e-6]))
    # slope -2 k (V - Vb) is O(1e-6 * 4e-6) next to the break: value and slope continuous
    assert abs(near[0] - near[1]) < 1e-12 and abs(dnear[0] - dnear[1]) < 1e-10


def test_table_alpha() -> None:
    schedule = TableAlpha([1000.0, 3000.0, 6000.0], [10.0, 20.0, 50.0])
    v = np.array([500.0, 2000.0, 3000.0, 4500.0, 7000.0])
    alpha, dalpha = schedule.alpha_deg(v)
    np.testing.assert_allclose(alpha, [10.0, 15.0, 20.0, 35.0, 50.0], rtol=EXACT_RTOL)
    # slope of the segment holding V (the upper one on a breakpoint), zero outside
    np.testing.assert_allclose(dalpha, [0.0, 0.005, 0.01, 0.01, 0.0], rtol=EXACT_RTOL)
    alpha_c, dalpha_c = schedule.alpha_deg(v + 1j * STEP)
    np.testing.assert_allclose(alpha_c.imag / STEP, dalpha, rtol=CS_RTOL)
    assert np.all(dalpha_c.imag == 0.0)
    with pytest.raises(ValueError, match="one value per"):
        TableAlpha([1.0, 2.0], [3.0])


def test_constant_alpha() -> None:
    alpha, dalpha = ConstantAlpha(25.0).alpha_deg(np.ones((2, 3)))
    assert alpha.shape == (2, 3) and np.all(alpha == 25.0) and np.all(dalpha == 0.0)


def test_aero_builders() -> None:
    poly = {"model": "polynomial", "cl_coefficients": LU_CL, "cd_coefficients": LU_CD}
    model = aero_from_spec({**poly, "cd_argument": "cl"})
    assert isinstance(model, PolynomialAero) and isinstance(model, AeroModel)
    assert model.cd_argument == "cl" and model.cl_coefficients == tuple(LU_CL)
    polar = SimpleNamespace(model="parabolic_polar", cl_star=0.4, cd0=0.04, k_induced=0.25)
    assert aero_from_spec(polar) == ParabolicPolarAero(0.4, 0.04, 0.25)
    table = SimpleNamespace(
        model="table",
        alpha_deg=[0.0, 40.0],
        mach=[2.0, 20.0],
        cl=[[0.0, 0.1], [1.0, 1.1]],
        cd=[[0.1, 0.1], [0.9, 0.8]],
        interpolation="cubic",
    )
    built = aero_from_spec(table)
    assert isinstance(built, TableAero) and built.interpolation == "cubic"
    assert built.coefficients(40.0, 20.0).cl == pytest.approx(1.1, rel=EXACT_RTOL)
    with pytest.raises(ValueError, match="unknown aerodynamics model"):
        aero_from_spec({"model": "newtonian"})


def test_alpha_schedule_builders() -> None:
    built = alpha_schedule_from_spec({"mode": "velocity_schedule"})
    assert built == VelocityScheduleAlpha() and isinstance(built, AlphaSchedule)
    custom = SimpleNamespace(
        mode="velocity_schedule",
        alpha_max_deg=30.0,
        velocity_break_m_s=4000.0,
        slope_coefficient=0.1,
        velocity_scale_m_s=300.0,
    )
    assert alpha_schedule_from_spec(custom) == VelocityScheduleAlpha(30.0, 4000.0, 0.1, 300.0)
    table = alpha_schedule_from_spec(
        {"mode": "table", "velocity_m_s": [1.0, 2.0], "alpha_deg": [3.0, 5.0]}
    )
    assert isinstance(table, TableAlpha) and table.alpha_deg(1.5)[0] == pytest.approx(4.0)
    constant = alpha_schedule_from_spec(SimpleNamespace(mode="constant", alpha_deg=12.0))
    assert isinstance(constant, ConstantAlpha) and constant.value_deg == 12.0
    assert alpha_schedule_from_spec({"mode": "optimized", "min_deg": 0.0, "max_deg": 40.0}) is None
    with pytest.raises(ValueError, match="unknown angle-of-attack mode"):
        alpha_schedule_from_spec({"mode": "bang-bang"})
