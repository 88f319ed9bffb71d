"""The reference of paper 003's SCP and everything the subproblem needs about it: the 8-state
dynamics and Jacobians at the mesh points, the collocation defects, the path limits and the
no-fly-zone distances with their gradients, and the penalized nonlinear cost that judges a step.

Path limits are linearized in log form, ln(value / limit) <= 0 (heat rate, dynamic pressure,
load factor): each is a product of powers of density, speed and an alpha factor, so its log is
nearly linear in (r, V, alpha).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from worker.solver.constraints.no_fly import zone_distance
from worker.solver.models.alpha_bank_state import (
    ALPHA,
    AlphaBankStateDerivatives,
    alpha_bank_state_dynamics,
)
from worker.solver.problem import EntryProblem
from worker.solver.transcription.cgl_collocation import CollocationPattern

Array = np.ndarray
R, THETA, PHI, V = 0, 1, 2, 3
_DEG_PER_RAD = 180.0 / math.pi


@dataclass
class HpIterate:
    """A reference: points z (K, 8), rates w (K, 2) = (bank rate, alpha rate), final time t_f
    (nondimensional), on ``pattern``'s mesh."""

    z: Array
    w: Array
    tf: float
    pattern: CollocationPattern
    multipliers: Array | None = None
    """mu (K, 8) of the subproblem that made this reference (``gathered_multipliers``)."""


@dataclass
class PathRows:
    """ln(value / limit) of each active path limit at the points (L, K) and its partials in r,
    V and alpha (radians)."""

    names: list[str]
    g: Array
    g_r: Array
    g_v: Array
    g_a: Array


@dataclass
class Linearization:
    """The reference's dynamics, defects, path and zone rows, and its penalized cost."""

    dyn: AlphaBankStateDerivatives
    defects: Array  # (K-1, 8) nondimensional
    path: PathRows
    zone_c: Array  # (Z, K) distance - radius (rad)
    zone_lat: Array  # (Z, K)
    zone_lon: Array  # (Z, K)
    between: PathRows | None = None
    """The path rows at the states interpolated between the points (the pattern's
    ``samples.between``), each sharing the slack of its nearest point (``between_owner``)."""
    between_owner: Array | None = None
    """The nearest point of each between-point sample (``PolynomialSamples.between_owner``)."""

    def path_excess(self) -> Array:
        """(L, K) excess of each path limit owned by each point: the larger of its own and of
        the between-point samples it owns, at least 0 (an L-infinity penalty locally)."""
        excess = np.maximum(self.path.g, 0.0)
        if self.between is not None and self.between_owner is not None and self.between.g.size:
            for i in range(excess.shape[0]):
                np.maximum.at(excess[i], self.between_owner, np.maximum(self.between.g[i], 0.0))
        return excess


def path_rows(problem: EntryProblem, z: Array, dyn: AlphaBankStateDerivatives) -> PathRows:
    """The log path rows at the points from the dynamics' force terms."""
    ft = dyn.forces
    lim = problem.limits
    r, v = z[:, R], z[:, V]
    names: list[str] = []
    rows: list[tuple[Array, Array, Array, Array]] = []
    ln_rho_r = ft.rho_r / ft.rho
    sc = problem.scales
    if lim.heat_max_W_m2 is not None and problem.heat_model is not None:
        heat = problem.heat_model
        qa, qa_a = heat.alpha_factor(ft.alpha_deg)
        v_dim = v * sc.speed_m_s
        base = heat.k_q * ft.rho**heat.density_exponent * v_dim**heat.velocity_exponent
        g = np.log(base * qa / lim.heat_max_W_m2)
        names.append("heat_rate")
        rows.append(
            (
                g,
                heat.density_exponent * ln_rho_r,
                heat.velocity_exponent / v,
                qa_a / qa * _DEG_PER_RAD,
            )
        )
    if lim.dynamic_pressure_max_Pa is not None:
        v_dim = v * sc.speed_m_s
        g = np.log(0.5 * ft.rho * v_dim * v_dim / lim.dynamic_pressure_max_Pa)
        names.append("dynamic_pressure")
        rows.append((g, ln_rho_r, 2.0 / v, np.zeros_like(r)))
    if lim.load_factor_max_g is not None:
        n2 = ft.lift * ft.lift + ft.drag * ft.drag
        g = 0.5 * np.log(n2) - math.log(lim.load_factor_max_g)
        names.append("load_factor")
        rows.append(
            (
                g,
                (ft.lift * ft.lift_r + ft.drag * ft.drag_r) / n2,
                (ft.lift * ft.lift_v + ft.drag * ft.drag_v) / n2,
                (ft.lift * ft.lift_a + ft.drag * ft.drag_a) / n2 * _DEG_PER_RAD,
            )
        )
    if not rows:
        empty = np.zeros((0, z.shape[0]))
        return PathRows([], empty, empty, empty, empty)
    g, gr, gv, ga = (np.array([row[i] for row in rows]) for i in range(4))
    return PathRows(names, g, gr, gv, ga)


def linearize(problem: EntryProblem, ref: HpIterate, jacobians: bool = True) -> Linearization:
    """Dynamics (F = t_f f), defects, path and zone rows at ``ref``'s points."""
    dyn = alpha_bank_state_dynamics(
        ref.z, ref.w, problem.forces, problem.omega, ref.tf, jacobians=jacobians
    )
    defects = ref.pattern.defects(ref.z, dyn.F)
    path = path_rows(problem, ref.z, dyn)
    zones = problem.no_fly_zones
    k = ref.z.shape[0]
    zc, zlat, zlon = np.zeros((len(zones), k)), np.zeros((len(zones), k)), np.zeros((len(zones), k))
    for i, zone in enumerate(zones):
        d = zone_distance(ref.z[:, PHI], ref.z[:, THETA], zone)
        zc[i], zlat[i], zlon[i] = d.c - zone.radius, d.c_lat, d.c_lon
    between, owner = None, None
    if path.g.size:
        sample = ref.pattern.samples
        z_s = np.einsum("sj,sja->sa", sample.between, ref.z[sample.between_idx])
        dyn_s = alpha_bank_state_dynamics(
            z_s,
            np.zeros((z_s.shape[0], 2)),
            problem.forces,
            problem.omega,
            ref.tf,
            jacobians=False,
        )
        between = path_rows(problem, z_s, dyn_s)
        owner = sample.between_owner
    return Linearization(dyn, defects, path, zc, zlat, zlon, between, owner)


def finite(lin: Linearization) -> bool:
    """Whether the reference's rates, defects and path rows are all finite (a step that left
    the models' range is not)."""
    return bool(
        np.isfinite(lin.dyn.F).all()
        and np.isfinite(lin.defects).all()
        and np.isfinite(lin.path.g).all()
        and (lin.between is None or np.isfinite(lin.between.g).all())
    )


__all__ = ["ALPHA", "HpIterate", "Linearization", "PathRows", "finite", "linearize", "path_rows"]


CURVATURE_STEP = 1.0e-6
"""Central-difference step of the curvature, in nondimensional state and rate units (the
density's exponential in the radius makes a forward difference's error about 1e-3)."""


def curvature_blocks(problem: EntryProblem, ref: HpIterate, mu: Array, units: Array) -> Array:
    """Convexified Hessians of the collocation rows' Lagrangian, one (10, 10) block per point in
    the scaled (z, w) variables: -sum_a mu_ja d2 F_a / dx2 at point j (F = t_f f), with
    mu_ja = sum_i c_ij lambda_(i,a) the rows' multipliers gathered at the point they integrate,
    by central differences of the analytic Jacobians, symmetrized and clipped to its nonnegative
    eigenvalues (the SQP step foh-ptr takes on its own discretization)."""
    k = ref.z.shape[0]
    x = np.concatenate([ref.z, ref.w], axis=1)  # (K, 10)

    def gradient(xx: Array) -> Array:
        d = alpha_bank_state_dynamics(xx[:, :8], xx[:, 8:], problem.forces, problem.omega, ref.tf)
        assert d.A is not None and d.B is not None
        jac = np.concatenate([d.A, d.B], axis=2)  # (K, 8, 10)
        return np.einsum("ka,kab->kb", mu, jac)

    H = np.empty((k, 10, 10))
    for c in range(10):
        step = np.zeros(10)
        step[c] = CURVATURE_STEP
        H[:, :, c] = (gradient(x + step[None, :]) - gradient(x - step[None, :])) / (
            2.0 * CURVATURE_STEP
        )
    H = -0.5 * (H + np.transpose(H, (0, 2, 1)))
    scale = units[None, :, None] * units[None, None, :]
    H *= scale
    vals, vecs = np.linalg.eigh(H)
    vals = np.maximum(vals, 0.0)
    return np.einsum("kij,kj,klj->kil", vecs, vals, vecs)


def gathered_multipliers(pattern: CollocationPattern, rows: Array) -> Array:
    """mu (K, 8): each collocation row's multiplier (unscaled rows, (K-1, 8)) times its
    coefficient c_ij, summed at the point j it integrates."""
    mu = np.zeros((pattern.num_points, rows.shape[1]))
    np.add.at(mu, pattern.pair_col, pattern.coef[:, None] * rows[pattern.pair_row - 1])
    return mu
