"""The energy range and the initial guess of paper 000's method (sec. 4)."""

from __future__ import annotations

import numpy as np

from worker.solver.models.layout import ENERGY
from worker.solver.problem import EntryProblem

Array = np.ndarray
TIME_INDEX = (0, 1, 2, 4, 5)
"""Where each energy-form state sits in the time-form state [r, theta, phi, V, gamma, psi]."""


def energy_bounds(problem: EntryProblem) -> tuple[float, float]:
    """Initial energy from the initial state; final from the document or terminal altitude+speed."""
    y0 = problem.y0
    e0 = 1.0 / y0[0] - 0.5 * y0[3] ** 2
    if problem.energy_final is not None:
        return e0, problem.energy_final
    alt = problem.terminal["altitude_m"]
    vel = problem.terminal["velocity_m_s"]
    if alt.kind != "fixed" or vel.kind != "fixed" or alt.value is None or vel.value is None:
        raise ValueError(
            "the final energy needs energy.final or a fixed terminal altitude and speed"
        )
    return e0, 1.0 / alt.value - 0.5 * vel.value**2


def initial_guess(problem: EntryProblem, e: Array) -> tuple[Array, Array]:
    """Straight line from initial to terminal state in energy, zero control (paper 000 sec. 4)."""
    x0 = problem.y0[list(TIME_INDEX)]
    xf = x0.copy()
    for j, key in ENERGY.terminal_states():
        target = problem.terminal[key].target()
        if target is not None:
            xf[j] = target
    s = (e - e[0]) / (e[-1] - e[0])
    x = x0[None, :] + s[:, None] * (xf - x0)[None, :]
    return x, np.zeros((e.size, 2))


def guess_in_energy(problem: EntryProblem, e: Array) -> tuple[Array, Array]:
    """The caller's initial guess (``problem.guess``) on the energy grid ``e``: its states
    interpolated in energy (its energy range mapped onto e's), the initial state at the first
    node, and the bank as the control [cos, sin] (the guess's bank within the bank range)."""
    assert problem.guess is not None
    y, bank = problem.guess.on_energies(e)
    x = y[:, list(TIME_INDEX)]
    x[0] = problem.y0[list(TIME_INDEX)]
    bank = np.clip(bank, problem.bank_min, problem.bank_max)
    return x, np.column_stack([np.cos(bank), np.sin(bank)])
