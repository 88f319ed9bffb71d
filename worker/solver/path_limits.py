"""Path quantities (heat rate, dynamic pressure, load factor) and their limits.

Values are SI (W/m^2, Pa, g) with partials in the nondimensional radius and speed. In the energy
domain, where V is fixed by (r, e), each limit becomes a lower bound on the radius (paper 000
eq. 15-16); ``radius_lower_bound`` finds it by bisection because with the exact speed
V(r, e) = sqrt(2(1/r - e)) the bound has no closed form.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worker.solver.forces import ForceTerms, VehicleForces
from worker.solver.polynomial import horner

Array = np.ndarray


@dataclass(frozen=True)
class HeatRateModel:
    """Qdot = k_q rho^n V^m qa(alpha), SI (paper 000 eq. 12; paper 004's alpha factor qa)."""

    k_q: float
    velocity_exponent: float = 3.15
    density_exponent: float = 0.5
    alpha_polynomial: tuple[float, ...] | None = None

    def alpha_factor(self, alpha_deg: Array) -> tuple[Array, Array]:
        """qa(alpha) and d qa / d alpha (alpha in degrees); (1, 0) when no polynomial is given."""
        if not self.alpha_polynomial:
            return np.ones_like(alpha_deg), np.zeros_like(alpha_deg)
        c = self.alpha_polynomial
        return horner(c, 0, len(c), alpha_deg)


@dataclass(frozen=True)
class PathLimits:
    """Optional upper limits on heat rate (W/m^2), dynamic pressure (Pa) and load factor (g)."""

    heat: HeatRateModel | None = None
    heat_max_W_m2: float | None = None
    dynamic_pressure_max_Pa: float | None = None
    load_factor_max_g: float | None = None

    @property
    def any(self) -> bool:
        return any(
            lim is not None
            for lim in (self.heat_max_W_m2, self.dynamic_pressure_max_Pa, self.load_factor_max_g)
        )


@dataclass
class PathValues:
    """Heat rate, dynamic pressure, load factor (SI) and their partials in (r, V) nondimensional."""

    heat_rate: Array
    heat_rate_r: Array
    heat_rate_v: Array
    dynamic_pressure: Array
    load_factor: Array
    heat_rate_a: Array | None = None
    """d heat rate / d alpha (per degree) at fixed (r, V), where alpha is a state."""


def path_values(
    forces: VehicleForces, heat: HeatRateModel | None, r: Array, v: Array, ft: ForceTerms
) -> PathValues:
    """Evaluate the path quantities from already computed force terms at (r, V)."""
    sc = forces.scales
    v_dim = v * sc.speed_m_s
    qbar = 0.5 * ft.rho * v_dim * v_dim
    nload = np.sqrt(ft.lift * ft.lift + ft.drag * ft.drag)
    if heat is None:
        zero = np.zeros_like(r)
        return PathValues(zero, zero, zero, qbar, nload)
    qa, qa_a = heat.alpha_factor(ft.alpha_deg)
    with np.errstate(invalid="ignore"):  # a diverged iterate's negative speed: NaN, reported
        base = heat.k_q * ft.rho**heat.density_exponent * v_dim**heat.velocity_exponent
    qdot = base * qa
    qdot_r = qdot * heat.density_exponent * ft.rho_r / ft.rho
    qdot_v = qdot * heat.velocity_exponent / v + base * qa_a * ft.alpha_v
    return PathValues(qdot, qdot_r, qdot_v, qbar, nload, base * qa_a)


def limit_ratio(forces: VehicleForces, limits: PathLimits, r: Array, v: Array) -> Array:
    """max over the active limits of value / limit (<= 1 means all limits hold).

    Values only (no partials): the same arithmetic as ``path_values`` on ``forces.terms``.
    """
    rho, lift, drag, alpha = forces.lift_drag(r, v)
    v_dim = v * forces.scales.speed_m_s
    ratio = np.zeros_like(r)
    if limits.heat_max_W_m2 is not None:
        heat = limits.heat
        if heat is None:
            heat_rate = np.zeros_like(r)
        else:
            qa, _ = heat.alpha_factor(alpha)
            with np.errstate(invalid="ignore"):  # as in ``path_values``
                base = heat.k_q * rho**heat.density_exponent * v_dim**heat.velocity_exponent
            heat_rate = base * qa
        ratio = np.maximum(ratio, heat_rate / limits.heat_max_W_m2)
    if limits.dynamic_pressure_max_Pa is not None:
        qbar = 0.5 * rho * v_dim * v_dim
        ratio = np.maximum(ratio, qbar / limits.dynamic_pressure_max_Pa)
    if limits.load_factor_max_g is not None:
        nload = np.sqrt(lift * lift + drag * drag)
        ratio = np.maximum(ratio, nload / limits.load_factor_max_g)
    return ratio


def radius_lower_bound(
    forces: VehicleForces,
    limits: PathLimits,
    e: Array,
    r_floor: float,
    r_ceiling: float,
    iterations: int = 14,
) -> tuple[Array, Array]:
    """Smallest radius at each energy where every path limit holds, by vectorized bisection.

    Assumes each path quantity decreases with altitude at fixed energy (denser air and higher
    speed lower down), which holds for the exponential and US76 atmospheres. 14 halvings bring a
    200 km bracket to ~12 m, where log(ratio) is linear in r to well below a millimetre, so one
    interpolation finishes the root (kept only where it satisfies the limits). Returns the bound
    (``r_floor`` where no limit binds) and a flag per node that is False where even
    ``r_ceiling`` violates a limit (the problem is infeasible there).
    """
    e = np.asarray(e, dtype=float)
    lo = np.full_like(e, r_floor)
    hi = np.minimum(np.full_like(e, r_ceiling), 1.0 / e * (1.0 - 1e-9))
    if not limits.any:
        return lo, np.ones_like(e, dtype=bool)

    def ratio(r: Array, e: Array) -> Array:
        v = np.sqrt(2.0 * (1.0 / r - e))
        return limit_ratio(forces, limits, r, v)

    # the ratio at both ends is kept along the bisection (it is needed again at the end)
    n = e.size
    both = ratio(np.concatenate([hi, lo]), np.concatenate([e, e]))
    ratio_hi, ratio_lo = both[:n], both[n:]
    feasible = ratio_hi <= 1.0
    unconstrained = ratio_lo <= 1.0
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        ratio_mid = ratio(mid, e)
        ok = ratio_mid <= 1.0
        hi = np.where(ok, mid, hi)
        lo = np.where(ok, lo, mid)
        ratio_hi = np.where(ok, ratio_mid, ratio_hi)
        ratio_lo = np.where(ok, ratio_lo, ratio_mid)
    g_lo, g_hi = np.log(ratio_lo), np.log(ratio_hi)
    with np.errstate(divide="ignore", invalid="ignore"):
        root = lo + (hi - lo) * g_lo / (g_lo - g_hi)
    root = np.where(np.isfinite(root) & (root >= lo) & (root <= hi), root, hi)
    root = np.where(ratio(root, e) <= 1.0 + 1e-12, root, hi)
    bound = np.where(unconstrained, r_floor, root)
    return bound, feasible
