"""An optimized angle of attack flown as paper 001's normalized lift: the problem the method
solves for a non-polar vehicle whose angle of attack it shapes, with alpha derived from the
lift share lam = CL(alpha, M) / CL(alpha_max, M) (``aero_models.LiftShareAero``)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from worker.solver.aero_models import AeroModel, LiftShareAero, ParabolicPolarAero
from worker.solver.aero_tables import TableAero
from worker.solver.models.point_mass import R, V
from worker.solver.problem import EntryProblem

Array = np.ndarray


def mach_samples(aero: AeroModel, first: float) -> list[float]:
    """The Mach numbers a lift share is checked at: ``first`` (where the best lift-to-drag share
    is found), then a table's Mach axis."""
    out = [first]
    if isinstance(aero, TableAero):
        out += [float(m) for m in aero.mach_grid]
    return out


def initial_mach(problem: EntryProblem) -> float:
    """The Mach number of the initial state."""
    forces, sc = problem.forces, problem.scales
    h = np.array([(problem.y0[R] - 1.0) * sc.radius_m])
    a, _ = forces.atmosphere.speed_of_sound(h)
    return float(problem.y0[V] * sc.speed_m_s / a[0])


def share_problem(problem: EntryProblem) -> EntryProblem:
    """``problem`` with its optimized angle of attack flown as a lift share (its aerodynamics
    the lift share's, its lift range [the smallest share, 1]); any other problem unchanged.
    ValueError where alpha cannot be derived from lam (``LiftShareAero.checked``)."""
    aero = problem.forces.aero
    if problem.alpha_range is None or isinstance(aero, ParabolicPolarAero):
        return problem
    lo, hi = (math.degrees(a) for a in problem.alpha_range)
    share = LiftShareAero.checked(aero, lo, hi, mach_samples(aero, initial_mach(problem)))
    forces = replace(problem.forces, aero=share)
    return replace(problem, forces=forces, lift_range=(share.min_share, 1.0))


def alpha_of_share(problem: EntryProblem, y: Array, lam: Array) -> Array:
    """The angle of attack (deg) of lift shares ``lam`` at states ``y`` (their Mach numbers)."""
    aero = problem.forces.aero
    assert isinstance(aero, LiftShareAero)
    sc = problem.scales
    a, _ = problem.forces.atmosphere.speed_of_sound((y[:, R] - 1.0) * sc.radius_m)
    return aero.alpha_of(lam, y[:, V] * sc.speed_m_s / a)
