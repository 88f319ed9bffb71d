"""Tabulated aerodynamic coefficients over (alpha, Mach): bilinear or cubic-spline interpolation.

Partials in both inputs; inputs off the table are clamped with a zero partial. Complex inputs
are evaluated by their first-order Taylor extension, so complex-step derivatives through the
tables equal their analytic derivatives.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
import numpy.typing as npt
from scipy.interpolate import RectBivariateSpline

from worker.solver.aero_models import AeroCoefficients, as_float_array

Array = npt.NDArray[Any]


def check_strictly_increasing(name: str, values: Array, minimum: int) -> None:
    """Raise ValueError unless ``values`` is 1-D, finite, strictly increasing, >= minimum long."""
    if values.ndim != 1 or values.size < minimum:
        raise ValueError(f"{name} must be a 1-D sequence of at least {minimum} values")
    if not np.all(np.isfinite(values)) or np.any(np.diff(values) <= 0.0):
        raise ValueError(f"{name} must be finite and strictly increasing")


def grid_cell(grid: Array, x: Array) -> tuple[Array, Array, Array]:
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
        xc, i, in_x = grid_cell(self.x, x)
        yc, j, in_y = grid_cell(self.y, y)
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
        xc, _, in_x = grid_cell(self.x, x)
        yc, _, in_y = grid_cell(self.y, y)
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
        check_strictly_increasing("alpha_deg", alpha_arr, 2)
        check_strictly_increasing("mach", mach_arr, 2)
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
        self.alpha_grid_deg = alpha_arr
        self.mach_grid = mach_arr

    def coefficients(self, alpha_deg: npt.ArrayLike, mach: npt.ArrayLike) -> AeroCoefficients:
        """Interpolated CL, CD and their partials (zero in an input that lies off the table)."""
        alpha, mach_arr = np.broadcast_arrays(as_float_array(alpha_deg), as_float_array(mach))
        cl, dcl_da, dcl_dm = _taylor_2d(self._cl, alpha, mach_arr)
        cd, dcd_da, dcd_dm = _taylor_2d(self._cd, alpha, mach_arr)
        return AeroCoefficients(cl, cd, dcl_da, dcd_da, dcl_dm, dcd_dm)
