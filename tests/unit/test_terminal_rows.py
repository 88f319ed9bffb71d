"""The shared terminal-rows helper: every kind of terminal condition on the bank-state and energy
layouts, hard or relaxed by a virtual-control buffer, and the soft and range row blocks it
gives both subproblem builders."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from app.schemas import ProblemDocument
from worker.solver.models.layout import BANK_STATE, ENERGY
from worker.solver.problem import EntryProblem, TerminalTarget, build_problem
from worker.solver.scenarios import get_scenario
from worker.solver.transcription.rows import Columns, RowSystem
from worker.solver.transcription.terminal import (
    TerminalRow,
    range_block,
    soft_block,
    terminal_rows,
)


@pytest.fixture(scope="module")
def problem() -> EntryProblem:
    """A problem with one terminal condition of every kind (velocity free)."""
    doc = ProblemDocument.model_validate(dict(get_scenario("rlv-max-terminal-velocity").problem))
    base = build_problem(doc)
    terminal = dict(base.terminal)
    terminal["altitude_m"] = TerminalTarget("fixed", value=1.004)
    terminal["longitude_deg"] = TerminalTarget("soft", value=0.2, weight=3.0)
    terminal["latitude_deg"] = TerminalTarget("range", lo=1.1, hi=1.3)
    terminal["velocity_m_s"] = TerminalTarget("free")
    terminal["flight_path_angle_deg"] = TerminalTarget("fixed", value=-0.1)
    terminal["heading_deg"] = TerminalTarget("free")
    return dataclasses.replace(base, terminal=terminal)


def test_hard_rows_on_the_energy_layout(problem: EntryProblem) -> None:
    rows = terminal_rows(problem, ENERGY, fixed="hard")
    assert rows == [
        TerminalRow(0, "fixed", value=1.004),
        TerminalRow(1, "soft", value=0.2, weight=3.0),
        TerminalRow(2, "range", lo=1.1, hi=1.3),
        TerminalRow(3, "fixed", value=-0.1),  # the energy form has no speed state
    ]


def test_virtual_rows_on_the_bank_state_layout(problem: EntryProblem) -> None:
    units = np.array([2.0, 4.0, 8.0, 16.0, 32.0, 64.0, 128.0])
    rows = terminal_rows(
        problem, BANK_STATE, fixed="virtual", virtual_weight=10.0, trust_units=units
    )
    assert rows == [
        TerminalRow(0, "soft", value=1.004, weight=10.0 / 2.0, virtual=True),
        TerminalRow(1, "soft", value=0.2, weight=3.0),
        TerminalRow(2, "range", lo=1.1, hi=1.3),
        TerminalRow(4, "soft", value=-0.1, weight=10.0 / 32.0, virtual=True),
    ]
    with pytest.raises(ValueError, match="trust units"):
        terminal_rows(problem, BANK_STATE, fixed="virtual", virtual_weight=1.0)


def test_soft_and_range_blocks() -> None:
    """|x_j - value| <= slack and lo <= x_j <= hi on the last node, in scaled deviations."""
    cols = Columns()
    last = cols.add("x", 3)
    slack = cols.add("slack", 1)
    scale = np.array([2.0, 3.0, 5.0])
    soft = [TerminalRow(1, "soft", value=0.5, weight=1.0)]
    ranges = [TerminalRow(2, "range", lo=-1.0, hi=2.0)]
    system = RowSystem(
        [
            soft_block(soft, last, slack, scale, lambda d: d),
            range_block(ranges, last, scale, lambda d: d),
        ],
        cols.n,
    )
    reference = np.array([0.0, 0.25, 0.5])
    np.testing.assert_array_equal(
        system.A(reference).toarray(),
        [[0, 3, 0, -1], [0, -3, 0, -1], [0, 0, 5, 0], [0, 0, -5, 0]],
    )
    np.testing.assert_array_equal(system.b(reference), [0.25, -0.25, 1.5, 1.5])
    assert system.cones.n_nonneg == 4
