"""Aerodynamic coefficient models: the interface, polynomial CL/CD and the parabolic polar.

Alpha is in degrees throughout, so every alpha derivative is per degree. Vectorized over nodes
and complex-safe (for complex-step Jacobian tests); polynomials are evaluated by
``polynomial.horner``, the same evaluation the compiled kernels use.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from worker.solver.polynomial import horner

Array = npt.NDArray[Any]


def as_float_array(x: npt.ArrayLike) -> Array:
    """``x`` as a float64 or complex128 array (integers promoted, complex kept)."""
    arr = np.asarray(x)
    return arr.astype(np.result_type(arr.dtype, np.float64), copy=False)


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
        alpha = as_float_array(alpha_deg)
        mach_arr = np.asarray(mach)
        if alpha.shape != mach_arr.shape:
            alpha, _ = np.broadcast_arrays(alpha, mach_arr)
        ncl, ncd = len(self.cl_coefficients), len(self.cd_coefficients)
        cl, dcl = horner(self.cl_coefficients, 0, ncl, alpha)
        if self.cd_argument == "cl":
            cd, dcd_dcl = horner(self.cd_coefficients, 0, ncd, cl)
            dcd = dcd_dcl * dcl
        else:
            cd, dcd = horner(self.cd_coefficients, 0, ncd, alpha)
        zero = np.zeros(alpha.shape)
        return AeroCoefficients(cl, cd, dcl, dcd, zero, zero.copy())


@dataclass(frozen=True)
class ParabolicPolarAero:
    """Parabolic polar with normalized lift lambda as control (paper 001): CL = lam*cl_star.

    CD = cd0 + k_induced CL^2. The vehicle has no angle of attack: its lift control is lam, and
    ``coefficients`` takes lam in the place of the angle of attack (the forces, the verification
    and the results pass the lift control of every vehicle through that one argument), with
    the partials in lam in the ``*_dalpha`` fields; Mach is ignored.
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
        lam_arr = as_float_array(lam)
        cl = lam_arr * self.cl_star
        cd = self.cd0 + self.k_induced * cl * cl
        dcl = np.full(lam_arr.shape, self.cl_star)
        return cl, cd, dcl, 2.0 * self.k_induced * cl * self.cl_star

    def coefficients(self, alpha_deg: npt.ArrayLike, mach: npt.ArrayLike) -> AeroCoefficients:
        """CL, CD and their lam partials at normalized lift ``alpha_deg`` (lam, see the class);
        Mach is ignored (zero partials)."""
        shape = np.broadcast_shapes(np.shape(alpha_deg), np.shape(mach))
        lam = np.broadcast_to(as_float_array(alpha_deg), shape)
        cl, cd, dcl, dcd = self.polar(lam)
        zero = np.zeros(shape)
        return AeroCoefficients(cl, cd, dcl, dcd, zero, zero.copy())


END_NUDGE_DEG = 1.0e-9
"""How far inside its bounds a lift share reads CL's slope at the bounds."""
LIFT_SHARE_NEWTON_STEPS = 60
"""Most safeguarded Newton steps of the inversion of CL(alpha, M) (each halves the bracket at
least when Newton leaves it: 60 reach round-off on any bracket of degrees); the loop ends
earlier at an exact fixed point, where more steps would change nothing."""


@dataclass(frozen=True)
class ShareAlpha:
    """The angle of attack of a lift share, its partials and what they were made of."""

    alpha_deg: Array
    alpha_lam: Array
    """d alpha / d lam (deg)."""
    alpha_mach: Array
    """d alpha / dM at fixed lam (deg)."""
    reference: Array
    """CL(alpha_max, M)."""
    reference_mach: Array
    base: AeroCoefficients
    """The vehicle's own coefficients at alpha."""


@dataclass(frozen=True)
class LiftShareAero:
    """An angle-of-attack vehicle flown by its lift share lam = CL(alpha, M) / CL(alpha_max, M):
    paper 001's normalized lift for any CL, CD model, alpha derived from lam by inverting CL at
    the Mach number (CL must increase with alpha over the bounds). ``coefficients`` takes lam in
    the angle of attack's place, as ``ParabolicPolarAero`` does, with the lam partials in the
    ``*_dalpha`` fields; lam = 1 is alpha_max, and beyond the bounds alpha is extrapolated along
    CL's end slope."""

    base: AeroModel
    alpha_min_deg: float
    alpha_max_deg: float
    best_share: float = 1.0
    """The lam of the best lift-to-drag ratio (at the Mach number it was found for)."""
    min_share: float = 0.0
    """The smallest lam that keeps alpha >= alpha_min at every Mach number checked, and >= 0."""

    @staticmethod
    def checked(
        base: AeroModel, alpha_min_deg: float, alpha_max_deg: float, machs: Sequence[float]
    ) -> LiftShareAero:
        """The lift share of ``base`` over [alpha_min, alpha_max], its best lift-to-drag share
        found at ``machs[0]``, its smallest share the largest CL(alpha_min, M) / CL(alpha_max,
        M) over ``machs`` (ValueError where CL does not increase with alpha over the bounds or
        CL(alpha_max, M) is not positive: alpha could not be derived from lam)."""
        grid = np.linspace(alpha_min_deg, alpha_max_deg, 721)
        grid[[0, -1]] += (END_NUDGE_DEG, -END_NUDGE_DEG)  # a table's own edge: its inner slope
        shares = []
        for mach in machs:
            c = base.coefficients(grid, np.full(grid.shape, float(mach)))
            if np.any(c.dcl_dalpha <= 0.0) or c.cl[-1] <= 0.0:
                bad = grid[int(np.argmin(c.dcl_dalpha))]
                raise ValueError(
                    f"CL must increase with alpha over [{alpha_min_deg}, {alpha_max_deg}] deg and "
                    f"be positive at the upper bound to derive alpha from the normalized lift; "
                    f"at Mach {mach:g} it does not (alpha {bad:.3g} deg, CL at the bound "
                    f"{c.cl[-1]:.4g})"
                )
            shares.append(float(c.cl[0] / c.cl[-1]))
        c0 = base.coefficients(grid, np.full(grid.shape, float(machs[0])))
        ratio = np.where(c0.cl > 0.0, c0.cl / np.maximum(c0.cd, 1e-300), -np.inf)
        best = float(c0.cl[int(np.argmax(ratio))] / c0.cl[-1])
        return LiftShareAero(base, alpha_min_deg, alpha_max_deg, best, max(0.0, *shares))

    def reference(self, mach: Array) -> tuple[Array, Array]:
        """CL(alpha_max, M) and its Mach partial: the lift of lam = 1."""
        c = self.base.coefficients(np.full(np.shape(mach), self.alpha_max_deg), mach)
        return c.cl, c.dcl_dmach

    def alpha_of(self, lam: npt.ArrayLike, mach: npt.ArrayLike) -> Array:
        """The angle of attack (deg) whose CL is lam CL(alpha_max, M), by bisection-safeguarded
        Newton on [alpha_min, alpha_max]; outside it, the end slope's extrapolation."""
        lam_a, mach_a = np.broadcast_arrays(
            np.asarray(lam, dtype=float), np.asarray(mach, dtype=float)
        )
        ref, _ = self.reference(mach_a)
        target = lam_a * ref
        lo = np.full(lam_a.shape, self.alpha_min_deg)
        hi = np.full(lam_a.shape, self.alpha_max_deg)
        c_lo = self.base.coefficients(lo, mach_a)
        below = target < c_lo.cl
        above = target > ref
        a = np.clip(lo + (target - c_lo.cl) / np.maximum(ref - c_lo.cl, 1e-300) * (hi - lo), lo, hi)
        for _ in range(LIFT_SHARE_NEWTON_STEPS):
            c = self.base.coefficients(a, mach_a)
            miss = c.cl - target
            hi = np.where(miss > 0.0, a, hi)
            lo = np.where(miss <= 0.0, a, lo)
            step = a - miss / np.where(c.dcl_dalpha > 0.0, c.dcl_dalpha, np.inf)
            inside = (step > lo) & (step < hi)
            moved = np.where(inside, step, 0.5 * (lo + hi))
            if np.array_equal(moved, a):  # a fixed point: further steps would repeat it
                break
            a = moved
        slope_lo, slope_hi = self._end_slopes(mach_a)
        a = np.where(below, self.alpha_min_deg + (target - c_lo.cl) / slope_lo, a)
        return np.where(above, self.alpha_max_deg + (target - ref) / slope_hi, a)

    def _end_slopes(self, mach: Array) -> tuple[Array, Array]:
        """dCL/dalpha just inside each bound (a table's own edge has no slope outwards)."""
        lo = self.base.coefficients(np.full(mach.shape, self.alpha_min_deg + END_NUDGE_DEG), mach)
        hi = self.base.coefficients(np.full(mach.shape, self.alpha_max_deg - END_NUDGE_DEG), mach)
        return lo.dcl_dalpha, hi.dcl_dalpha

    def alpha_partials(self, lam: npt.ArrayLike, mach: npt.ArrayLike) -> ShareAlpha:
        """The angle of attack (deg) of lift shares ``lam`` at Mach numbers ``mach`` with its
        partials, from CL(alpha, M) = lam CL_ref(M): d alpha/d lam = CL_ref / CL_alpha and
        d alpha/dM = (lam CL_ref' - CL_M) / CL_alpha (beyond the bounds, the extrapolation's)."""
        shape = np.broadcast_shapes(np.shape(lam), np.shape(mach))
        lam_a = np.broadcast_to(np.asarray(lam, dtype=float), shape)
        mach_a = np.broadcast_to(np.asarray(mach, dtype=float), shape)
        alpha = self.alpha_of(lam_a, mach_a)
        ref, ref_m = self.reference(mach_a)
        c = self.base.coefficients(alpha, mach_a)
        slope_lo, slope_hi = self._end_slopes(mach_a)
        slope = np.where(alpha > self.alpha_max_deg, slope_hi, c.dcl_dalpha)
        slope = np.where(alpha < self.alpha_min_deg, slope_lo, slope)
        return ShareAlpha(alpha, ref / slope, (lam_a * ref_m - c.dcl_dmach) / slope, ref, ref_m, c)

    def coefficients(self, alpha_deg: npt.ArrayLike, mach: npt.ArrayLike) -> AeroCoefficients:
        """CL = lam CL_ref(M), CD(alpha(lam, M), M) and their lam and Mach partials at lift share
        ``alpha_deg`` (lam, see the class), through :meth:`alpha_partials`."""
        shape = np.broadcast_shapes(np.shape(alpha_deg), np.shape(mach))
        lam = np.broadcast_to(np.asarray(alpha_deg, dtype=float), shape)
        share = self.alpha_partials(lam, mach)
        ref, ref_m, c = share.reference, share.reference_mach, share.base
        a_lam, a_mach = share.alpha_lam, share.alpha_mach
        return AeroCoefficients(
            cl=lam * ref,
            cd=c.cd,
            dcl_dalpha=ref,
            dcd_dalpha=c.dcd_dalpha * a_lam,
            dcl_dmach=lam * ref_m,
            dcd_dmach=c.dcd_dalpha * a_mach + c.dcd_dmach,
        )
