"""Paper 003's stage 3 for this method: assess the reference's mesh (each interval's propagated
end-state error and its excess over bounds and path limits between points) and split the
intervals that fail, carrying the reference onto the new mesh."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.schemas.methods.hp_scp import HpScpOptions
from worker.solver.methods.hp_scp.linearization import HpIterate, path_rows
from worker.solver.models.alpha_bank_state import ALPHA, SIGMA, alpha_bank_state_dynamics
from worker.solver.models.point_mass import time_dynamics
from worker.solver.problem import EntryProblem
from worker.solver.transcription.cgl_collocation import CollocationPattern, PolynomialAttitude
from worker.solver.transcription.cgl_mesh_refine import (
    carry,
    fine_times,
    interval_errors,
    interval_fraction,
    split,
)

Array = np.ndarray


@dataclass(frozen=True)
class MeshAssessment:
    """Per interval: end-state error (trust units), excess over bounds and limits between
    points (relative), and where in the interval the excess peaks; which intervals fail."""

    error: Array
    excess: Array
    peak: Array
    marked: Array

    def summary(self) -> dict[str, float | int]:
        """The figures a history record carries."""
        return {
            "max_interval_error": float(np.max(self.error)),
            "max_between_points_excess": float(np.max(self.excess)),
            "intervals_marked": int(np.count_nonzero(self.marked)),
        }


def between_points_excess(problem: EntryProblem, ref: HpIterate) -> tuple[Array, Array]:
    """Largest relative excess of bank, alpha and the path limits between points, per
    interval, on the fine grid of the mesh's polynomials, and where it peaks."""
    mesh = ref.pattern.mesh
    t, which = fine_times(mesh, ref.tf)
    z = mesh.interpolate(ref.z, 0.0, ref.tf, t)
    ratios = []
    span = problem.bank_max - problem.bank_min
    ratios.append((z[:, SIGMA] - problem.bank_max) / span)
    ratios.append((problem.bank_min - z[:, SIGMA]) / span)
    if problem.alpha_range is not None:
        lo, hi = problem.alpha_range
        ratios.append((z[:, ALPHA] - hi) / (hi - lo))
        ratios.append((lo - z[:, ALPHA]) / (hi - lo))
    attitude = PolynomialAttitude(mesh, ref.tf, ref.z[:, SIGMA], ref.z[:, ALPHA])
    bank_rate, alpha_rate = attitude.rates_at(t)
    for rate, limit in ((bank_rate, problem.bank_rate_max), (alpha_rate, problem.alpha_rate_max)):
        if limit is not None:
            ratios.append(np.abs(rate) / limit - 1.0)
    dyn = alpha_bank_state_dynamics(
        z, np.zeros((t.size, 2)), problem.forces, problem.omega, jacobians=False
    )
    path = path_rows(problem, z, dyn)
    ratios.extend(np.expm1(path.g))
    worst = np.max(np.array(ratios), axis=0)
    excess = np.zeros(mesh.num_intervals)
    peak = np.full(mesh.num_intervals, np.nan)
    for k in range(mesh.num_intervals):
        mask = which == k
        if not np.any(mask):
            continue
        i = int(np.argmax(np.where(mask, worst, -np.inf)))
        excess[k] = max(float(worst[i]), 0.0)
        if excess[k] > 0.0:
            peak[k] = interval_fraction(mesh, k, float(t[i]), ref.tf)
    return excess, peak


def assess(
    problem: EntryProblem, ref: HpIterate, units: Array, options: HpScpOptions
) -> MeshAssessment:
    """The reference's mesh against the refinement tolerances of ``options``."""
    mesh = ref.pattern.mesh
    attitude = PolynomialAttitude(mesh, ref.tf, ref.z[:, SIGMA], ref.z[:, ALPHA])

    def rates(t: Array, y: Array, att: Array) -> Array:
        u = np.column_stack([np.cos(att[:, 0]), np.sin(att[:, 0])])
        alpha = np.degrees(att[:, 1])
        dyn = time_dynamics(y, u, problem.forces, problem.omega, alpha, jacobians=False)
        return ref.tf * dyn.f

    def attitude_at(tau: Array) -> Array:
        bank, alpha_deg = attitude.at(tau * ref.tf)
        return np.column_stack([bank, np.radians(alpha_deg)])

    # integrated in normalized time tau = t / t_f (the rates scaled by t_f)
    error = interval_errors(mesh, 1.0, ref.z, rates, attitude_at, units, 6)
    excess, peak = between_points_excess(problem, ref)
    marked = (error > options.mesh_error_tolerance) | (excess > options.mesh_excess_tolerance)
    return MeshAssessment(error, excess, peak, marked)


def refined(ref: HpIterate, assessment: MeshAssessment, max_points: int) -> HpIterate | None:
    """The reference carried onto the mesh with the marked intervals split, or None when no
    interval is marked or the point budget allows no split."""
    if not np.any(assessment.marked):
        return None
    old = ref.pattern.mesh
    new = split(old, assessment.marked, assessment.peak, max_points)
    if new.num_points == old.num_points:
        return None
    pattern = CollocationPattern.of(new, ref.z.shape[1], ref.w.shape[1])
    return HpIterate(
        carry(old, new, ref.tf, ref.z), carry(old, new, ref.tf, ref.w), ref.tf, pattern
    )
