"""The model a time-domain FOH subproblem discretizes: the bank-state model of paper 002, or
the same with the angle of attack as a second state and its rate as a second control (an
optimized angle of attack, as paper 003 flies the Shuttle), or with a parabolic polar's
normalized lift in alpha's place (paper 001's vehicle)."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

from worker.solver.models.alpha_bank_state import ALPHA, alpha_bank_state_dynamics
from worker.solver.models.layout import (
    ALPHA_BANK_STATE,
    BANK_STATE,
    LIFT_BANK_STATE,
    StateLayout,
)
from worker.solver.problem import EntryProblem
from worker.solver.transcription.foh_exact import Dynamics


@dataclass(frozen=True)
class FohModel:
    """States (``layout``), number of controls (the rates of the attitude states), the
    dynamics (None: the bank-state model, compiled when the forces allow) and the index of the
    angle-of-attack state (None: alpha is scheduled)."""

    layout: StateLayout
    controls: int
    dynamics: Dynamics | None
    alpha: int | None
    unit: float = 1.0
    """The aerodynamic model's argument per unit of the alpha state: degrees per radian for
    an angle of attack, 1 for a polar's normalized lift (taken in alpha's place)."""

    @property
    def bank(self) -> int:
        """Index of the bank state."""
        return self.layout.index("bank_deg")


DEG_PER_RAD = 180.0 / math.pi

BANK_MODEL = FohModel(BANK_STATE, 1, None, None)
ALPHA_BANK_MODEL = FohModel(ALPHA_BANK_STATE, 2, alpha_bank_state_dynamics, ALPHA, DEG_PER_RAD)
LIFT_BANK_MODEL = FohModel(
    LIFT_BANK_STATE, 2, functools.partial(alpha_bank_state_dynamics, unit=1.0), ALPHA, 1.0
)


def foh_model(problem: EntryProblem) -> FohModel:
    """The alpha-bank model for an optimized angle of attack, the lift-bank model for a
    parabolic polar, else the bank-state model."""
    if problem.lift_range is not None:
        return LIFT_BANK_MODEL
    return ALPHA_BANK_MODEL if problem.alpha_optimized else BANK_MODEL


def lift_state_range(problem: EntryProblem) -> tuple[float, float] | None:
    """The alpha state's range in its own units (radians of alpha, or lambda), else None."""
    if problem.lift_range is not None:
        return problem.lift_range
    return problem.alpha_range if problem.alpha_optimized else None
