"""Aerodynamic coefficient models and angle-of-attack schedules with analytic derivatives.

Alpha is in degrees throughout, so every alpha derivative is per degree. Vectorized over nodes.
Polynomial, parabolic-polar, velocity-schedule and constant models are complex-safe (for
complex-step Jacobian tests); the table models accept complex input through their first-order
Taylor extension, so complex-step derivatives through them equal their analytic derivatives.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt
from scipy.interpolate import RectBivariateSpline

Array = npt.NDArray[Any]

_MISSING = object()


def _as_float_array(x: npt.ArrayLike) -> Array:
    """``x`` as a float64 or complex128 array (integers promoted, complex kept)."""
    arr = np.asarray(x)
    return arr.astype(np.result_type(arr.dtype, np.float64), copy=False)


def _spec_value(spec: Any, name: str, default: Any = _MISSING) -> Any:
    """Field ``name`` of a mapping or attribute object, else ``default`` (KeyError if none)."""
    value = spec.get(name, default) if isinstance(spec, Mapping) else getattr(spec, name, default)
    if value is _MISSING:
        raise KeyError(f"specification has no field {name!r}")
    return value


def _strictly_increasing(name: str, values: Array, minimum: int) -> None:
    """Raise ValueError unless ``values`` is 1-D, finite, strictly increasing, >= minimum long."""
    if values.ndim != 1 or values.size < minimum:
        raise ValueError(f"{name} must be a 1-D sequence of at least {minimum} values")
    if not np.all(np.isfinite(values)) or np.any(np.diff(values) <= 0.0):
        raise ValueError(f"{name} must be finite and strictly increasing")


@dataclass
class AeroCoefficients:
    """Lift and drag coefficients and their partials in alpha (per degree) and Mach."""

    cl: Array
    cd: Array
    dcl_dalpha: Array
    dcd_dalpha: Array
    dcl_dmach: Array
    dcd_dmach: Array


@runtime_checkable
class AeroModel(Protocol):
    """Maps angle of attack (deg) and Mach number to CL, CD and their partials."""

    def coefficients(self, alpha_deg: Array, mach: Array) -> AeroCoefficients:
        """CL, CD and partials at each node (inputs broadcast together)."""
        ...


def _polyval(coefficients: Sequence[float], x: Array) -> tuple[Array, Array]:
    """p(x) = sum_k c_k x^k (lowest order first) and p'(x), by Horner's rule; complex-safe.

    Horner's first two steps are written out (value c_n x + c_(n-1), slope c_n), which for
    finite x gives the very same numbers as starting the recursion from zero.
    """
    if len(coefficients) < 2:
        value = np.zeros_like(x)
        slope = np.zeros_like(x)
        for c in reversed(coefficients):
            slope = slope * x + value
            value = value * x + c
        return value, slope
    slope = np.full(np.shape(x), coefficients[-1], dtype=np.result_type(x, np.float64))
    value = coefficients[-1] * x + coefficients[-2]
    for c in reversed(coefficients[:-2]):
        slope = slope * x + value
        value = value * x + c
    return value, slope


class PolynomialAero:
    """CL = sum c_k alpha^k; CD = sum d_k alpha^k or sum d_k CL^k; Mach-independent, complex-safe.

    Papers 000/002/003 (Lu 1997): CL = -0.041065 + 0.016292 a + 0.0002602 a^2 with
    CD = 0.080505 - 0.03026 CL + 0.86495 CL^2 (``cd_argument="cl"``); paper 004 (Betts, Space
    Shuttle): CL = -0.20704 + 0.029244 a, CD = 0.07854 - 0.61592e-2 a + 0.621408e-3 a^2.
    """

    def __init__(
        self,
        cl_coefficients: Sequence[float],
        cd_coefficients: Sequence[float],
        cd_argument: Literal["alpha", "cl"],
    ) -> None:
        """Coefficients lowest order first; ``cd_argument`` is the CD polynomial's input."""
        if cd_argument not in ("alpha", "cl"):
            raise ValueError(f"cd_argument must be 'alpha' or 'cl', got {cd_argument!r}")
        self.cl_coefficients = tuple(float(c) for c in cl_coefficients)
        self.cd_coefficients = tuple(float(c) for c in cd_coefficients)
        for name, coeffs in (("cl", self.cl_coefficients), ("cd", self.cd_coefficients)):
            if not coeffs or not all(math.isfinite(c) for c in coeffs):
                raise ValueError(f"{name}_coefficients must be a non-empty list of finite numbers")
        self.cd_argument: Literal["alpha", "cl"] = cd_argument

    def coefficients(self, alpha_deg: npt.ArrayLike, mach: npt.ArrayLike) -> AeroCoefficients:
        """CL, CD and partials; the Mach partials are zero (the polynomials ignore Mach)."""
        alpha = _as_float_array(alpha_deg)
        mach_arr = np.asarray(mach)
        if alpha.shape != mach_arr.shape:
            alpha, _ = np.broadcast_arrays(alpha, mach_arr)
        cl, dcl = _polyval(self.cl_coefficients, alpha)
        if self.cd_argument == "cl":
            cd, dcd_dcl = _polyval(self.cd_coefficients, cl)
            dcd = dcd_dcl * dcl
        else:
            cd, dcd = _polyval(self.cd_coefficients, alpha)
        zero = np.zeros(alpha.shape)
        return AeroCoefficients(cl, cd, dcl, dcd, zero, zero.copy())


@dataclass(frozen=True)
class ParabolicPolarAero:
    """Parabolic polar with normalized lift lambda as control (paper 001): CL = lam*cl_star.

    CD = cd0 + k_induced CL^2. ``coefficients`` has no angle of attack to use: it ignores alpha
    and Mach and returns the lam = 1 point (CL = cl_star, the maximum-L/D lift coefficient
    when cl_star^2 = cd0/k_induced) with zero partials; the solver controls lam via ``polar``.
    """

    cl_star: float
    cd0: float
    k_induced: float

    def __post_init__(self) -> None:
        """Reject non-positive or non-finite parameters."""
        for name in ("cl_star", "cd0", "k_induced"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a positive finite number, got {value!r}")

    def polar(self, lam: npt.ArrayLike) -> tuple[Array, Array, Array, Array]:
        """(CL, CD, dCL/dlam, dCD/dlam) at normalized lift ``lam``; complex-safe."""
        lam_arr = _as_float_array(lam)
        cl = lam_arr * self.cl_star
        cd = self.cd0 + self.k_induced * cl * cl
        dcl = np.full(lam_arr.shape, self.cl_star)
        return cl, cd, dcl, 2.0 * self.k_induced * cl * self.cl_star

    def coefficients(self, alpha_deg: npt.ArrayLike, mach: npt.ArrayLike) -> AeroCoefficients:
        """The lam = 1 coefficients broadcast to the inputs' shape; alpha and Mach are ignored."""
        shape = np.broadcast_shapes(np.shape(alpha_deg), np.shape(mach))
        cl, cd, _, _ = self.polar(np.ones(shape))
        zero = np.zeros(shape)
        return AeroCoefficients(cl, cd, zero, zero.copy(), zero.copy(), zero.copy())


def _cell(grid: Array, x: Array) -> tuple[Array, Array, Array]:
    """Clamped ``x``, index of the grid cell holding it, and a mask of points inside the grid."""
    inside = (x >= grid[0]) & (x <= grid[-1])
    xc = np.clip(x, grid[0], grid[-1])
    index = np.clip(np.searchsorted(grid, xc, side="right") - 1, 0, grid.size - 2)
    return xc, index, inside


class _Bilinear:
    """Bilinear interpolant on a rectangular grid with partials (piecewise constant per cell)."""

    def __init__(self, x: Array, y: Array, values: Array) -> None:
        """Grid ``x`` (rows), ``y`` (columns) and ``values`` of shape (len(x), len(y))."""
        self.x, self.y, self.values = x, y, values

    def evaluate(
        self, x: Array, y: Array
    ) -> tuple[Array, Array, Array, Array, Array, Array, Array, Array]:
        """f, f_x, f_y, f_xx, f_xy, f_yy at clamped (x, y), plus the inside masks of x and y."""
        xc, i, in_x = _cell(self.x, x)
        yc, j, in_y = _cell(self.y, y)
        hx = self.x[i + 1] - self.x[i]
        hy = self.y[j + 1] - self.y[j]
        t = (xc - self.x[i]) / hx
        s = (yc - self.y[j]) / hy
        f00, f10 = self.values[i, j], self.values[i + 1, j]
        f01, f11 = self.values[i, j + 1], self.values[i + 1, j + 1]
        f = (1 - t) * (1 - s) * f00 + t * (1 - s) * f10 + (1 - t) * s * f01 + t * s * f11
        fx = ((1 - s) * (f10 - f00) + s * (f11 - f01)) / hx
        fy = ((1 - t) * (f01 - f00) + t * (f11 - f10)) / hy
        fxy = (f11 - f10 - f01 + f00) / (hx * hy)
        zero = np.zeros_like(f)
        return f, fx, fy, zero, fxy, zero, in_x, in_y


class _Spline:
    """Interpolating ``RectBivariateSpline`` (cubic where the grid allows) with its partials."""

    def __init__(self, x: Array, y: Array, values: Array) -> None:
        """Grid ``x`` (rows), ``y`` (columns) and ``values`` of shape (len(x), len(y))."""
        self.x, self.y = x, y
        self.kx, self.ky = min(3, x.size - 1), min(3, y.size - 1)
        self.spline = RectBivariateSpline(x, y, values, kx=self.kx, ky=self.ky, s=0.0)

    def _partial(self, x: Array, y: Array, dx: int, dy: int) -> Array:
        """d^(dx+dy) f / dx^dx dy^dy at in-range points (dx, dy <= 2).

        FITPACK only evaluates derivative orders below the degree. A degree below 3 means the
        axis has degree + 1 points, hence no interior knots: along it the spline is a single
        polynomial, so a derivative of order equal to the degree is constant there and is the
        exact divided difference of the next lower one between the axis ends.
        """
        if dx > self.kx or dy > self.ky:
            return np.zeros(x.shape)
        if dx == self.kx:
            lo, hi = self.x[0], self.x[-1]
            upper = self._partial(np.full(x.shape, hi), y, dx - 1, dy)
            return (upper - self._partial(np.full(x.shape, lo), y, dx - 1, dy)) / (hi - lo)
        if dy == self.ky:
            lo, hi = self.y[0], self.y[-1]
            upper = self._partial(x, np.full(y.shape, hi), dx, dy - 1)
            return (upper - self._partial(x, np.full(y.shape, lo), dx, dy - 1)) / (hi - lo)
        return np.asarray(self.spline.ev(x, y, dx=dx, dy=dy), dtype=float)

    def evaluate(
        self, x: Array, y: Array
    ) -> tuple[Array, Array, Array, Array, Array, Array, Array, Array]:
        """f, f_x, f_y, f_xx, f_xy, f_yy at clamped (x, y), plus the inside masks of x and y."""
        xc, _, in_x = _cell(self.x, x)
        yc, _, in_y = _cell(self.y, y)
        orders = ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))
        f, fx, fy, fxx, fxy, fyy = (self._partial(xc, yc, i, j) for i, j in orders)
        return f, fx, fy, fxx, fxy, fyy, in_x, in_y


def _taylor_2d(interp: _Bilinear | _Spline, x: Array, y: Array) -> tuple[Array, Array, Array]:
    """Value and partials at (x, y), clamped (zero partial off the grid); complex via Taylor."""
    f, fx, fy, fxx, fxy, fyy, in_x, in_y = interp.evaluate(x.real, y.real)
    fx, fxx = np.where(in_x, fx, 0.0), np.where(in_x, fxx, 0.0)
    fy, fyy = np.where(in_y, fy, 0.0), np.where(in_y, fyy, 0.0)
    fxy = np.where(in_x & in_y, fxy, 0.0)
    if np.iscomplexobj(x) or np.iscomplexobj(y):
        dx, dy = np.imag(x), np.imag(y)
        return (
            f + 1j * (dx * fx + dy * fy),
            fx + 1j * (dx * fxx + dy * fxy),
            fy + 1j * (dx * fxy + dy * fyy),
        )
    return f, fx, fy


class TableAero:
    """CL and CD tabulated over (alpha in deg, Mach) and interpolated with partials in both.

    ``interpolation="linear"``: bilinear, partials piecewise constant per cell (on a cell edge
    the cell above is used). ``"cubic"``: interpolating ``RectBivariateSpline`` of degree 3 per
    axis (lower where an axis has fewer than 4 points). Outside the table each input is clamped
    to the table's edge and the partial in that input is zero. Complex inputs are evaluated by
    the first-order Taylor extension f(x) + i (dy . grad f), so complex steps reproduce the
    analytic partials.
    """

    def __init__(
        self,
        alpha_deg: npt.ArrayLike,
        mach: npt.ArrayLike,
        cl: npt.ArrayLike,
        cd: npt.ArrayLike,
        interpolation: Literal["linear", "cubic"] = "linear",
    ) -> None:
        """Axes (strictly increasing, >= 2 points), tables shaped (len(alpha), len(mach))."""
        alpha_arr = np.asarray(alpha_deg, dtype=float)
        mach_arr = np.asarray(mach, dtype=float)
        _strictly_increasing("alpha_deg", alpha_arr, 2)
        _strictly_increasing("mach", mach_arr, 2)
        tables = {"cl": np.asarray(cl, dtype=float), "cd": np.asarray(cd, dtype=float)}
        for name, table in tables.items():
            if table.shape != (alpha_arr.size, mach_arr.size):
                raise ValueError(
                    f"{name} has shape {table.shape}; expected ({alpha_arr.size}, {mach_arr.size})"
                )
            if not np.all(np.isfinite(table)):
                raise ValueError(f"{name} must contain only finite values")
        if interpolation == "linear":
            self._cl: _Bilinear | _Spline = _Bilinear(alpha_arr, mach_arr, tables["cl"])
            self._cd: _Bilinear | _Spline = _Bilinear(alpha_arr, mach_arr, tables["cd"])
        elif interpolation == "cubic":
            self._cl = _Spline(alpha_arr, mach_arr, tables["cl"])
            self._cd = _Spline(alpha_arr, mach_arr, tables["cd"])
        else:
            raise ValueError(f"interpolation must be 'linear' or 'cubic', got {interpolation!r}")
        self.interpolation = interpolation

    def coefficients(self, alpha_deg: npt.ArrayLike, mach: npt.ArrayLike) -> AeroCoefficients:
        """Interpolated CL, CD and their partials (zero in an input that lies off the table)."""
        alpha, mach_arr = np.broadcast_arrays(_as_float_array(alpha_deg), _as_float_array(mach))
        cl, dcl_da, dcl_dm = _taylor_2d(self._cl, alpha, mach_arr)
        cd, dcd_da, dcd_dm = _taylor_2d(self._cd, alpha, mach_arr)
        return AeroCoefficients(cl, cd, dcl_da, dcd_da, dcl_dm, dcd_dm)


@runtime_checkable
class AlphaSchedule(Protocol):
    """Angle of attack prescribed as a function of speed."""

    def alpha_deg(self, v_m_s: Array) -> tuple[Array, Array]:
        """Alpha (deg) and d alpha/dV (deg per m/s) at speeds ``v_m_s``."""
        ...


@dataclass(frozen=True)
class VelocityScheduleAlpha:
    """alpha = alpha_max above V_break, else alpha_max - slope (V - V_break)^2 / scale^2.

    Paper 000 eq. 9 (from Wang & Grant 2017). The derivative is continuous (zero) at the break.
    Complex-safe: the branch is chosen on the real part of V.
    """

    alpha_max_deg: float = 40.0
    velocity_break_m_s: float = 4570.0
    slope_coefficient: float = 0.20705
    velocity_scale_m_s: float = 340.0

    def __post_init__(self) -> None:
        """Reject non-finite parameters and a non-positive velocity scale."""
        for name in ("alpha_max_deg", "velocity_break_m_s", "slope_coefficient"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be finite")
        if not (math.isfinite(self.velocity_scale_m_s) and self.velocity_scale_m_s > 0.0):
            raise ValueError("velocity_scale_m_s must be a positive finite number")

    def alpha_deg(self, v_m_s: npt.ArrayLike) -> tuple[Array, Array]:
        """Alpha (deg) and d alpha/dV (deg per m/s)."""
        v = _as_float_array(v_m_s)
        k = self.slope_coefficient / self.velocity_scale_m_s**2
        dv = v - self.velocity_break_m_s
        low = v.real <= self.velocity_break_m_s
        alpha = np.where(low, self.alpha_max_deg - k * dv * dv, self.alpha_max_deg)
        return alpha, np.where(low, -2.0 * k * dv, 0.0)


class TableAlpha:
    """Alpha (deg) linearly interpolated in speed; clamped outside the table (zero derivative).

    The derivative is the slope of the segment holding V (the segment above on a breakpoint).
    Complex speeds are evaluated by the first-order Taylor extension alpha(x) + iy alpha'(x).
    """

    def __init__(self, velocity_m_s: npt.ArrayLike, alpha_deg: npt.ArrayLike) -> None:
        """Breakpoints (strictly increasing) and alpha values of the same length (>= 1)."""
        self.velocity_m_s = np.asarray(velocity_m_s, dtype=float)
        self.alpha_values = np.asarray(alpha_deg, dtype=float)
        _strictly_increasing("velocity_m_s", self.velocity_m_s, 1)
        if self.alpha_values.shape != self.velocity_m_s.shape:
            raise ValueError("alpha_deg must have one value per velocity_m_s breakpoint")
        if not np.all(np.isfinite(self.alpha_values)):
            raise ValueError("alpha_deg must contain only finite values")

    def alpha_deg(self, v_m_s: npt.ArrayLike) -> tuple[Array, Array]:
        """Alpha (deg) and d alpha/dV (deg per m/s)."""
        v = _as_float_array(v_m_s)
        x = v.real
        alpha = np.interp(x, self.velocity_m_s, self.alpha_values)
        if self.velocity_m_s.size == 1:
            slope = np.zeros(x.shape)
        else:
            _, i, inside = _cell(self.velocity_m_s, x)
            seg = np.diff(self.alpha_values) / np.diff(self.velocity_m_s)
            slope = np.where(inside, seg[i], 0.0)
        if np.iscomplexobj(v):
            return alpha + 1j * v.imag * slope, slope + 0j
        return alpha, slope


class ConstantAlpha:
    """A fixed angle of attack (deg) with zero derivative."""

    def __init__(self, alpha_deg: float) -> None:
        """The fixed angle of attack in degrees (finite)."""
        if not math.isfinite(alpha_deg):
            raise ValueError("alpha_deg must be finite")
        self.value_deg = float(alpha_deg)

    def alpha_deg(self, v_m_s: npt.ArrayLike) -> tuple[Array, Array]:
        """The fixed alpha shaped like ``v_m_s`` and a zero derivative."""
        shape = np.shape(v_m_s)
        return np.full(shape, self.value_deg), np.zeros(shape)


def aero_from_spec(spec: Any) -> AeroModel:
    """Build the aerodynamic model described by a schema object or plain dict (``model``)."""
    model = _spec_value(spec, "model")
    if model == "polynomial":
        return PolynomialAero(
            list(_spec_value(spec, "cl_coefficients")),
            list(_spec_value(spec, "cd_coefficients")),
            _spec_value(spec, "cd_argument"),
        )
    if model == "parabolic_polar":
        return ParabolicPolarAero(
            cl_star=float(_spec_value(spec, "cl_star")),
            cd0=float(_spec_value(spec, "cd0")),
            k_induced=float(_spec_value(spec, "k_induced")),
        )
    if model == "table":
        return TableAero(
            _spec_value(spec, "alpha_deg"),
            _spec_value(spec, "mach"),
            _spec_value(spec, "cl"),
            _spec_value(spec, "cd"),
            _spec_value(spec, "interpolation", "linear"),
        )
    raise ValueError(
        f"unknown aerodynamics model {model!r}; expected 'polynomial', 'parabolic_polar' or 'table'"
    )


def alpha_schedule_from_spec(spec: Any) -> AlphaSchedule | None:
    """Build the angle-of-attack schedule of a schema object or dict; None when optimized."""
    mode = _spec_value(spec, "mode")
    if mode == "velocity_schedule":
        return VelocityScheduleAlpha(
            alpha_max_deg=float(_spec_value(spec, "alpha_max_deg", 40.0)),
            velocity_break_m_s=float(_spec_value(spec, "velocity_break_m_s", 4570.0)),
            slope_coefficient=float(_spec_value(spec, "slope_coefficient", 0.20705)),
            velocity_scale_m_s=float(_spec_value(spec, "velocity_scale_m_s", 340.0)),
        )
    if mode == "table":
        return TableAlpha(_spec_value(spec, "velocity_m_s"), _spec_value(spec, "alpha_deg"))
    if mode == "constant":
        return ConstantAlpha(float(_spec_value(spec, "alpha_deg")))
    if mode == "optimized":
        return None
    raise ValueError(
        f"unknown angle-of-attack mode {mode!r}; "
        "expected 'velocity_schedule', 'table', 'constant' or 'optimized'"
    )
