"""Angle-of-attack schedules: alpha (deg) and d alpha / dV as functions of speed (m/s).

Velocity schedule (paper 000 eq. 9), linear table and constant; complex-safe (the table through
its first-order Taylor extension).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from worker.solver.aero_models import as_float_array
from worker.solver.aero_tables import check_strictly_increasing, grid_cell

Array = npt.NDArray[Any]


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
        v = as_float_array(v_m_s)
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
        check_strictly_increasing("velocity_m_s", self.velocity_m_s, 1)
        if self.alpha_values.shape != self.velocity_m_s.shape:
            raise ValueError("alpha_deg must have one value per velocity_m_s breakpoint")
        if not np.all(np.isfinite(self.alpha_values)):
            raise ValueError("alpha_deg must contain only finite values")

    def alpha_deg(self, v_m_s: npt.ArrayLike) -> tuple[Array, Array]:
        """Alpha (deg) and d alpha/dV (deg per m/s)."""
        v = as_float_array(v_m_s)
        x = v.real
        alpha = np.interp(x, self.velocity_m_s, self.alpha_values)
        if self.velocity_m_s.size == 1:
            slope = np.zeros(x.shape)
        else:
            _, i, inside = grid_cell(self.velocity_m_s, x)
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
