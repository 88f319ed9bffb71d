"""Atmosphere models: published values, derivatives (complex step, finite differences), builders."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from worker.solver.atmosphere import (
    Atmosphere,
    ExponentialAtmosphere,
    US76Atmosphere,
    atmosphere_from_spec,
)

STEP = 1e-30  # complex step: no subtractive cancellation, so the step can be tiny
CS_RTOL = 1e-10  # complex step is exact to rounding; 1e-10 leaves room for a few operations


def _heights() -> np.ndarray:
    """Altitudes over the whole US76 range, plus points outside it (extrapolated)."""
    rng = np.random.default_rng(3)
    inside = np.concatenate([rng.uniform(0.0, 150e3, 300), rng.uniform(150e3, 1000e3, 100)])
    # 71801 m and 51412 m sit in the shortest grid cells (next to the layer bases)
    return np.concatenate([inside, [-500.0, 1.1e6, 71801.0, 51412.0]])


def test_exponential_values() -> None:
    atm = ExponentialAtmosphere(rho0=1.225, scale_height_m=7200.0)
    rho, _ = atm.density(np.array([0.0, 7200.0]))
    # closed form, a single exp: 1e-15 relative is the rounding of one operation
    np.testing.assert_allclose(rho, [1.225, 1.225 / np.e], rtol=1e-15)
    a, da = atm.speed_of_sound(np.zeros((2, 3)))
    assert a.shape == (2, 3) and np.all(a == 295.07) and np.all(da == 0.0)


def test_exponential_derivative_complex_step() -> None:
    atm = ExponentialAtmosphere(rho0=1.2, scale_height_m=8000.0)
    h = np.linspace(-2e3, 120e3, 50)
    _, drho = atm.density(h)
    rho_c, _ = atm.density(h + 1j * STEP)
    np.testing.assert_allclose(drho, rho_c.imag / STEP, rtol=CS_RTOL)


@pytest.mark.parametrize("field", ["rho0", "scale_height_m", "speed_of_sound_m_s"])
def test_exponential_rejects_bad_parameters(field: str) -> None:
    params = {"rho0": 1.225, "scale_height_m": 7200.0, "speed_of_sound_m_s": 295.07}
    params[field] = -1.0
    with pytest.raises(ValueError, match=field):
        ExponentialAtmosphere(**params)


# U.S. Standard Atmosphere 1976 tables (geometric altitude), printed to 5 significant digits
# (4 at 86 and 100 km).
PUBLISHED_RHO = [(0.0, 1.2250), (10e3, 0.41351), (50e3, 1.0269e-3), (86e3, 6.958e-6)]
PUBLISHED_SOUND = [(0.0, 340.29), (10e3, 299.53), (50e3, 329.80), (86e3, 274.10)]


@pytest.mark.parametrize(("h", "rho_ref"), PUBLISHED_RHO)
def test_us76_density_published(h: float, rho_ref: float) -> None:
    rho, _ = US76Atmosphere().density(np.array([h]))
    # 1e-4: half a unit in the 4th-5th printed digit (<= 7e-5); these altitudes are grid nodes
    assert rho[0] == pytest.approx(rho_ref, rel=1e-4)


def test_us76_density_published_thermosphere() -> None:
    rho, _ = US76Atmosphere().density(np.array([100e3]))
    # 3e-3: the ussa1976 package integrates the thermosphere's diffusion equations itself and
    # gives 5.612e-7 against the printed 5.604e-7 (0.15 %); the grid adds < 1e-4
    assert rho[0] == pytest.approx(5.604e-7, rel=3e-3)


@pytest.mark.parametrize(("h", "a_ref"), PUBLISHED_SOUND)
def test_us76_speed_of_sound_published(h: float, a_ref: float) -> None:
    a, _ = US76Atmosphere().speed_of_sound(np.array([h]))
    # 0.006 m/s: half a unit in the printed 2nd decimal, plus rounding
    assert a[0] == pytest.approx(a_ref, abs=0.006)


def test_us76_matches_package_between_nodes() -> None:
    import ussa1976

    z = np.linspace(13.7, 999.9e3, 4001)  # off the grid nodes
    ds = ussa1976.compute(z, variables=["rho", "cs"])
    atm = US76Atmosphere()
    rho, _ = atm.density(z)
    # 5e-4: PCHIP smooths the tropopause's slope break (a 0.03/km jump of d ln(rho)/dh) over
    # one 100 m cell, error ~ jump * cell / 8 = 3.8e-4; elsewhere the error is below 1e-4
    np.testing.assert_allclose(rho, ds["rho"].values, rtol=5e-4)
    low = z <= 86e3
    a, _ = atm.speed_of_sound(z[low])
    # 3e-4: same smoothing argument for the temperature profile's slope breaks
    np.testing.assert_allclose(a, ds["cs"].values[low], rtol=3e-4)


def test_us76_derivatives_finite_difference() -> None:
    atm = US76Atmosphere()
    h = _heights()
    delta = 0.01  # m
    _, drho = atm.density(h)
    fd = (atm.density(h + delta)[0] - atm.density(h - delta)[0]) / (2 * delta)
    # 2e-6: truncation delta^2 f'''/6 peaks at 2e-7 in the 2 m cell by the 71 km layer base;
    # rounding eps * H / delta is ~1e-10
    np.testing.assert_allclose(drho, fd, rtol=2e-6)
    _, da = atm.speed_of_sound(h)
    fd_a = (atm.speed_of_sound(h + delta)[0] - atm.speed_of_sound(h - delta)[0]) / (2 * delta)
    # absolute (da/dh is zero in isothermal layers): truncation peaks at 6e-9 1/s, and
    # rounding eps * 1700 m/s / delta is 4e-11 1/s
    np.testing.assert_allclose(da, fd_a, rtol=0.0, atol=1e-7)


@pytest.mark.parametrize("node", [0.0, 11019.067832, 71801.9706747, 86e3, 150e3, 1000e3])
def test_us76_derivatives_continuous(node: float) -> None:
    atm = US76Atmosphere()
    h = np.array([node - 1e-7, node + 1e-7])
    _, drho = atm.density(h)
    _, da = atm.speed_of_sound(h)
    # C1 interpolant (and C1 linear continuation beyond the ends): the sides differ by f'' *
    # 2e-7 m; |(ln rho)''| <= 2e-6 /m^2 even in the shortest cells, so < 3e-9 relative in
    # drho/dh, and |a''| <= 1e-3 1/(s m) gives < 2e-10 1/s in da/dh
    assert drho[0] == pytest.approx(drho[1], rel=1e-8)
    assert da[0] == pytest.approx(da[1], abs=1e-9)


def test_us76_monotone_and_positive() -> None:
    h = np.linspace(-1e3, 1.01e6, 200001)
    rho, drho = US76Atmosphere().density(h)
    a, _ = US76Atmosphere().speed_of_sound(h)
    assert np.all(rho > 0.0) and np.all(np.diff(rho) < 0.0) and np.all(drho < 0.0)
    assert np.all(a > 250.0)


def test_us76_complex_input_is_first_order_taylor() -> None:
    atm = US76Atmosphere()
    h = _heights()
    rho, drho = atm.density(h)
    rho_c, drho_c = atm.density(h + 1j * STEP)
    np.testing.assert_allclose(rho_c.real, rho, rtol=1e-15)  # exp of an unchanged real part
    np.testing.assert_allclose(rho_c.imag / STEP, drho, rtol=CS_RTOL)
    # the derivative's imaginary part carries rho'' = rho (L'' + L'^2); compare with a
    # central difference of drho (step 0.01 m, truncation as in the derivative test)
    d2 = (atm.density(h + 0.01)[1] - atm.density(h - 0.01)[1]) / 0.02
    np.testing.assert_allclose(drho_c.imag / STEP, d2, rtol=1e-3, atol=1e-20)
    _, da = atm.speed_of_sound(h)
    a_c, _ = atm.speed_of_sound(h + 1j * STEP)
    np.testing.assert_allclose(a_c.imag / STEP, da, rtol=CS_RTOL, atol=1e-300)


def test_builders_from_mapping_and_attributes() -> None:
    spec = {"model": "exponential", "scale_height_m": 8420.0}
    atm = atmosphere_from_spec(spec)
    assert isinstance(atm, ExponentialAtmosphere) and isinstance(atm, Atmosphere)
    assert (atm.rho0, atm.scale_height_m, atm.speed_of_sound_m_s) == (1.225, 8420.0, 295.07)
    obj = SimpleNamespace(
        model="exponential",
        density_sea_level_kg_m3=1.2,
        scale_height_m=7000.0,
        speed_of_sound_m_s=300.0,
    )
    atm = atmosphere_from_spec(obj)
    assert atm == ExponentialAtmosphere(rho0=1.2, scale_height_m=7000.0, speed_of_sound_m_s=300.0)
    assert isinstance(atmosphere_from_spec({"model": "us76"}), US76Atmosphere)
    assert isinstance(atmosphere_from_spec(SimpleNamespace(model="us76")), US76Atmosphere)


def test_builder_errors() -> None:
    with pytest.raises(ValueError, match="unknown atmosphere model"):
        atmosphere_from_spec({"model": "mars"})
    with pytest.raises(KeyError, match="scale_height_m"):
        atmosphere_from_spec({"model": "exponential"})
