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
