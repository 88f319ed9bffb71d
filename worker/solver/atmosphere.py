"""Atmosphere models: density and speed of sound with their altitude derivatives (SI).

Vectorized over nodes. The exponential model is analytic and complex-safe (for complex-step
Jacobian tests); the tabulated US76 model accepts complex altitudes through its first-order
Taylor extension, so complex-step derivatives of anything built on it equal its analytic ones.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt
from scipy.interpolate import PchipInterpolator

Array = npt.NDArray[Any]

_MISSING = object()


@runtime_checkable
class Atmosphere(Protocol):
    """Density and speed of sound as functions of geometric altitude, with d/dh."""

    def density(self, h_m: Array) -> tuple[Array, Array]:
        """Density rho (kg/m^3) and d rho / dh (kg/m^4) at altitudes ``h_m`` (m)."""
        ...

    def speed_of_sound(self, h_m: Array) -> tuple[Array, Array]:
        """Speed of sound a (m/s) and da/dh (1/s) at altitudes ``h_m`` (m)."""
        ...


def _as_float_array(x: npt.ArrayLike) -> Array:
    """``x`` as a float64 or complex128 array (integers promoted, complex kept)."""
    arr = np.asarray(x)
    return arr.astype(np.result_type(arr.dtype, np.float64), copy=False)


@dataclass(frozen=True, kw_only=True)
class ExponentialAtmosphere:
    """Isothermal exponential atmosphere rho = rho0 exp(-h/hs) (paper 000 eq. 4); complex-safe.

    The model has no temperature, so ``speed_of_sound_m_s`` is a constant used only to form a
    Mach number for Mach-dependent aerodynamics; its altitude derivative is zero.
    """

    rho0: float = 1.225
    scale_height_m: float
    speed_of_sound_m_s: float = 295.07

    def __post_init__(self) -> None:
        """Reject non-positive or non-finite parameters."""
        for name in ("rho0", "scale_height_m", "speed_of_sound_m_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a positive finite number, got {value!r}")

    def density(self, h_m: npt.ArrayLike) -> tuple[Array, Array]:
        """rho = rho0 exp(-h/hs) and d rho/dh = -rho/hs."""
        h = _as_float_array(h_m)
        rho = self.rho0 * np.exp(-h / self.scale_height_m)
        return rho, -rho / self.scale_height_m

    def speed_of_sound(self, h_m: npt.ArrayLike) -> tuple[Array, Array]:
        """The constant speed of sound and a zero derivative, shaped like ``h_m``."""
        h = _as_float_array(h_m)
        return np.full(h.shape, self.speed_of_sound_m_s), np.zeros(h.shape)


# Geopotential heights (m) of the bases of the US76 temperature layers 1..6 (the standard's
# layer table), made grid nodes so the temperature profile's slope breaks fall on nodes.
_US76_LAYER_BASES_GEOPOTENTIAL_M = (11000.0, 20000.0, 32000.0, 47000.0, 51000.0, 71000.0)
_US76_EARTH_RADIUS_M = 6356766.0  # r0 of the geopotential relation H = r0 Z / (r0 + Z), US76 eq. 18
_US76_GAS_CONSTANT = 8.31432  # R*, J/(mol K), US76 adopted constant
_US76_AVOGADRO = 6.022169e23  # N_A, 1/mol, US76 adopted constant
_US76_GAMMA = 1.4  # ratio of specific heats used by the standard's speed of sound, US76 eq. 50
_US76_TOP_M = 1000e3


@dataclass(frozen=True)
class _Curve:
    """A C1 piecewise-cubic curve on [x0, x1], continued linearly (C1) beyond both ends."""

    f: PchipInterpolator
    df: PchipInterpolator
    d2f: PchipInterpolator
    x0: float
    x1: float

    def evaluate(self, x: Array) -> tuple[Array, Array, Array]:
        """Value, first and second derivative at real ``x`` (linear continuation outside)."""
        xc = np.clip(x, self.x0, self.x1)
        inside = (x >= self.x0) & (x <= self.x1)
        slope = self.df(xc)
        value = self.f(xc) + slope * (x - xc)
        curvature = np.where(inside, self.d2f(xc), 0.0)
        return value, slope, curvature


@dataclass(frozen=True)
class _US76Tables:
    """log(rho) and speed of sound of US76 as C1 curves in geometric altitude."""

    log_rho: _Curve
    sound: _Curve


def _us76_grid() -> Array:
    """Altitude nodes (m): 100 m apart to 150 km plus the layer bases, then 1 km to 1000 km."""
    h_layers = np.asarray(_US76_LAYER_BASES_GEOPOTENTIAL_M)
    z_layers = _US76_EARTH_RADIUS_M * h_layers / (_US76_EARTH_RADIUS_M - h_layers)
    fine = np.linspace(0.0, 150e3, 1501)
    coarse = np.linspace(150e3, _US76_TOP_M, 851)
    return np.unique(np.concatenate([fine, z_layers, coarse]))


def _curve(x: Array, y: Array) -> _Curve:
    """Monotone-preserving C1 (PCHIP) interpolant of ``y(x)`` with its derivatives."""
    f = PchipInterpolator(x, y, extrapolate=False)
    return _Curve(f, f.derivative(1), f.derivative(2), float(x[0]), float(x[-1]))


@lru_cache(maxsize=1)
def _us76_tables() -> _US76Tables:
    """Evaluate the ``ussa1976`` package once on the grid and build the interpolants (cached)."""
    import ussa1976  # deferred: pulls in xarray, only needed when US76 is used

    z = _us76_grid()
    ds = ussa1976.compute(z, variables=["t", "rho", "n_tot"])
    rho = np.asarray(ds["rho"].values, dtype=float)
    temperature = np.asarray(ds["t"].values, dtype=float)
    n_tot = np.asarray(ds["n_tot"].values, dtype=float)
    molar_mass = rho * _US76_AVOGADRO / n_tot  # kg/mol; equals M0 below 86 km
    sound = np.sqrt(_US76_GAMMA * _US76_GAS_CONSTANT * temperature / molar_mass)
    return _US76Tables(log_rho=_curve(z, np.log(rho)), sound=_curve(z, sound))


class US76Atmosphere:
    """U.S. Standard Atmosphere 1976, 0-1000 km, from the ``ussa1976`` package, interpolated.

    The standard is evaluated once (cached, shared by all instances) on a grid of 100 m up to
    150 km (with nodes at the temperature-layer bases) and 1 km above, then log(rho) and the
    speed of sound are interpolated with PCHIP, so both and their derivatives are continuous
    and rho stays monotone. The interpolant smooths the slope breaks of the standard's
    piecewise temperature profile over one grid cell; its largest relative departure from the
    standard is about 2.5e-4 in rho (next to the 11 km tropopause) and 1e-4 in a.

    Speed of sound: a = sqrt(gamma R* T / M) with gamma = 1.4 (US76 eq. 50). Up to 86 km this is
    the standard's value; above, where the standard defines none, it is the same formula with
    the kinetic temperature and the local mean molar mass (continuous at 86 km), a
    continuation that only matters where dynamic pressure is negligible.

    Outside 0-1000 km both log(rho) and a are continued linearly with their end slopes (C1;
    below 0 km this prolongs the troposphere's local scale height and lapse rate).
    Real altitudes give real results. A complex altitude x + iy is evaluated by the first-order
    Taylor extension f(x) + iy f'(x) (and f'(x) + iy f''(x) for the derivative), so complex-step
    differentiation of a model built on this atmosphere reproduces these analytic derivatives.
    """

    def density(self, h_m: npt.ArrayLike) -> tuple[Array, Array]:
        """rho (kg/m^3) and d rho/dh (kg/m^4); see the class docstring for range and accuracy."""
        h = _as_float_array(h_m)
        log_rho, slope, curvature = _us76_tables().log_rho.evaluate(h.real)
        if np.iscomplexobj(h):
            log_rho = log_rho + 1j * h.imag * slope
            slope = slope + 1j * h.imag * curvature
        rho = np.exp(log_rho)
        return rho, rho * slope

    def speed_of_sound(self, h_m: npt.ArrayLike) -> tuple[Array, Array]:
        """a (m/s) and da/dh (1/s); see the class docstring for the definition above 86 km."""
        h = _as_float_array(h_m)
        a, slope, curvature = _us76_tables().sound.evaluate(h.real)
        if np.iscomplexobj(h):
            return a + 1j * h.imag * slope, slope + 1j * h.imag * curvature
        return a, slope


def _spec_value(spec: Any, name: str, default: Any = _MISSING) -> Any:
    """Field ``name`` of a mapping or attribute object, else ``default`` (KeyError if none)."""
    value = spec.get(name, default) if isinstance(spec, Mapping) else getattr(spec, name, default)
    if value is _MISSING:
        raise KeyError(f"specification has no field {name!r}")
    return value


def atmosphere_from_spec(spec: Any) -> Atmosphere:
    """Build the atmosphere described by a schema object or plain dict (``model`` selects it)."""
    model = _spec_value(spec, "model")
    if model == "exponential":
        return ExponentialAtmosphere(
            rho0=float(_spec_value(spec, "density_sea_level_kg_m3", 1.225)),
            scale_height_m=float(_spec_value(spec, "scale_height_m")),
            speed_of_sound_m_s=float(_spec_value(spec, "speed_of_sound_m_s", 295.07)),
        )
    if model == "us76":
        return US76Atmosphere()
    raise ValueError(f"unknown atmosphere model {model!r}; expected 'exponential' or 'us76'")
