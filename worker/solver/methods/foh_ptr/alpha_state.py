"""What an optimized angle of attack (or a polar's normalized lift, in its place) adds to the
time-domain method: a held value for the constant-control start, the start's alpha column, and
the flown attitude between the nodes.

The start flies the bank sweep of paper 002 at one held angle of attack, the given initial one
or else the one of the largest lift-to-drag ratio within the range (the longest glide, so that
far targets are reached), then the alpha state starts from it with zero rate.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from worker.solver.alpha_schedules import ConstantAlpha
from worker.solver.problem import EntryProblem
from worker.solver.trajectory import OptimizedTrajectory, held_quadratic
from worker.solver.transcription.foh_model import FohModel, lift_state_range
from worker.solver.transcription.foh_subproblem import AlphaBounds
from worker.solver.transcription.time_grid import (
    InitialGuessError,
    Reference,
    guess_reference,
    initial_reference,
)

Array = np.ndarray

GLIDE_MACH = 10.0
"""Mach number at which the start's lift-to-drag ratio is compared (hypersonic glide)."""
ALPHA_SAMPLES = 181
"""Angles of attack compared over the range (a quarter degree over 45 deg)."""


def held_alpha(problem: EntryProblem, unit: float) -> float:
    """The start's alpha state (its own units; ``unit``: the aerodynamic argument per unit of
    it): the given initial angle of attack, else the largest lift-to-drag ratio's within the
    range at ``GLIDE_MACH``."""
    if problem.initial_alpha is not None and problem.lift_range is None:
        return problem.initial_alpha
    bounds = lift_state_range(problem)
    assert bounds is not None
    alphas = np.linspace(bounds[0] * unit, bounds[1] * unit, ALPHA_SAMPLES)
    c = problem.forces.aero.coefficients(alphas, np.full(alphas.shape, GLIDE_MACH))
    ratio = np.where(c.cd > 0, c.cl / np.where(c.cd > 0, c.cd, 1.0), -np.inf)
    return float(alphas[int(np.argmax(ratio))]) / unit


def held_alpha_problem(problem: EntryProblem, alpha: float, unit: float) -> EntryProblem:
    """The same problem flown at a constant alpha state ``alpha`` (``unit`` as ``held_alpha``):
    the bank-state sweep of the start runs on it."""
    forces = dataclasses.replace(problem.forces, alpha_schedule=ConstantAlpha(alpha * unit))
    return dataclasses.replace(
        problem, forces=forces, alpha_optimized=False, alpha_range=None, lift_range=None
    )


def with_alpha(ref: Reference, alpha: Array | float) -> Reference:
    """The bank-state reference with the alpha state appended (``alpha`` radians, at every node
    or one value) and zero rates of both attitude states."""
    k = ref.z.shape[0]
    column = np.broadcast_to(np.asarray(alpha, dtype=float), (k,))
    rates = np.zeros((k, 2))
    rates[:, 0] = ref.w
    return Reference(z=np.column_stack([ref.z, column]), w=rates, s=ref.s, bank_deg=ref.bank_deg)


def held_start(
    problem: EntryProblem, unit: float, nodes: int, start_bank_deg: float | None
) -> Reference | InitialGuessError:
    """The start with an alpha state: the caller's guess (its angle of attack where it gives
    one; a polar's normalized lift starts held) or the bank-state start, each flown at the held
    alpha (``held_alpha``), the alpha column appended; or why there is none."""
    alpha = held_alpha(problem, unit)
    held = held_alpha_problem(problem, alpha, unit)
    try:
        if problem.guess is not None:
            ref = guess_reference(held, nodes)
            times = np.concatenate([[0.0], np.cumsum(ref.s)])
            given = problem.guess.alpha_on_times(times) if problem.lift_range is None else None
            return with_alpha(ref, given if given is not None else alpha)
        return with_alpha(initial_reference(held, nodes, start_bank_deg), alpha)
    except InitialGuessError as exc:
        return exc


def alpha_bounds(problem: EntryProblem, index: int | None) -> AlphaBounds | None:
    """An alpha state's index, range and rate bound (an optimized angle of attack's, or a
    polar's normalized lift without a rate bound), else None."""
    bounds = lift_state_range(problem)
    if index is None or bounds is None:
        return None
    rate = problem.alpha_rate_max if problem.lift_range is None else None
    return AlphaBounds(index, bounds[0], bounds[1], rate)


def held_trajectory(t: Array, z: Array, w: Array, model: FohModel) -> OptimizedTrajectory:
    """The nodes (K, 8) at times ``t`` with both attitude states held by their rates ``w``
    (K, 2) between them, as the verification flies them."""
    sigma, alpha = model.bank, model.alpha
    assert alpha is not None
    return OptimizedTrajectory(
        "time",
        t,
        z[:, :6].copy(),
        t,
        z[:, sigma].copy(),
        alpha_deg=z[:, alpha] * model.unit,
        bank_rate=w[:, 0].copy(),
        attitude=HeldAttitude(t, z[:, sigma].copy(), z[:, alpha].copy(), w.copy(), model.unit),
    )


@dataclasses.dataclass(frozen=True)
class HeldAttitude:
    """Bank and angle of attack between the nodes as the subproblem holds them: each rate
    linear over an interval (first-order hold), so each angle is quadratic there."""

    t: Array  # (K,) nondimensional times of the nodes
    bank: Array  # (K,) radians
    alpha: Array  # (K,) the alpha state (radians, or a polar's lambda)
    rates: Array  # (K, 2) d bank/dt, d alpha/dt (state units per nondimensional time)
    unit: float = 180.0 / math.pi  # the aerodynamic argument per unit of the alpha state

    @property
    def breaks(self) -> Array:
        """Where the pieces meet: the nodes."""
        return self.t

    def at(self, t: Array) -> tuple[Array, Array]:
        """(bank in radians, angle of attack in degrees or a polar's lambda) at times ``t``."""
        t = np.asarray(t, dtype=float)
        bank = held_quadratic(self.t, self.bank, self.rates[:, 0], t)
        alpha = held_quadratic(self.t, self.alpha, self.rates[:, 1], t)
        return bank, alpha * self.unit

    def rates_at(self, t: Array) -> tuple[Array, Array]:
        """(d bank/dt, d alpha/dt) at times ``t``, radians per nondimensional time."""
        t = np.asarray(t, dtype=float)
        return (
            np.interp(t, self.t, self.rates[:, 0]),
            np.interp(t, self.t, self.rates[:, 1]),
        )
