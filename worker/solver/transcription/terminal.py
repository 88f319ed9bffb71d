"""Terminal conditions as rows of a subproblem, shared by the time- and energy-domain builders.

``terminal_rows`` turns a problem's terminal conditions into ``TerminalRow`` s on a model's
states (hard fixed rows, or fixed rows relaxed by an L1 buffer as PTR's virtual control, paper
002 sec. IV); ``soft_block`` and ``range_block`` are their nonnegative row blocks on the last
node, the same in both transcriptions.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal, TypeVar

import numpy as np

from worker.solver.models.layout import StateLayout
from worker.solver.problem import EntryProblem
from worker.solver.transcription.rows import RowBlock, Term

Array = np.ndarray
D = TypeVar("D")


@dataclass(frozen=True)
class TerminalRow:
    """One terminal condition on one state of the layout, in nondimensional units."""

    state: int
    kind: Literal["fixed", "soft", "range"]
    value: float = 0.0
    lo: float = 0.0
    hi: float = 0.0
    weight: float = 0.0
    virtual: bool = False  # a fixed condition relaxed by an L1-penalized buffer (PTR)


def terminal_rows(
    problem: EntryProblem,
    layout: StateLayout,
    *,
    fixed: Literal["hard", "virtual"],
    virtual_weight: float = 0.0,
    trust_units: np.ndarray | None = None,
) -> list[TerminalRow]:
    """The terminal conditions of ``problem`` on the terminal states of ``layout``, in order.

    With ``fixed="virtual"`` a fixed condition becomes a soft row flagged ``virtual`` whose
    weight is ``virtual_weight / trust_units[j]`` (the buffer is penalized in trust units);
    with ``"hard"`` it stays an equality.
    """
    if fixed == "virtual" and trust_units is None:
        raise ValueError("virtual terminal rows need the trust units of their weights")
    rows: list[TerminalRow] = []
    for j, key in layout.terminal_states():
        t = problem.terminal[key]
        if t.kind == "fixed":
            value = float(t.value or 0.0)
            if fixed == "virtual":
                assert trust_units is not None
                weight = virtual_weight / trust_units[j]
                rows.append(TerminalRow(j, "soft", value=value, weight=weight, virtual=True))
            else:
                rows.append(TerminalRow(j, "fixed", value=value))
        elif t.kind == "soft":
            rows.append(TerminalRow(j, "soft", value=float(t.value or 0.0), weight=t.weight))
        elif t.kind == "range":
            rows.append(TerminalRow(j, "range", lo=float(t.lo or 0.0), hi=float(t.hi or 0.0)))
    return rows


def soft_block(
    soft: Sequence[TerminalRow],
    last: Array,
    slack: Array,
    scale: Array,
    final: Callable[[D], Array],
) -> RowBlock[D]:
    """Two rows per soft condition, +-(scale_j dx_j - target offset) <= slack: |x_j - value|
    <= slack on the last node. ``last``: the last node's state columns; ``slack``: one column
    per condition; ``final(d)``: the reference's last node."""
    states = np.array([t.state for t in soft], dtype=np.int64)
    values = np.array([t.value for t in soft], dtype=float)
    pair = np.arange(len(soft))[:, None] * 2 + np.array([0, 1])[None, :]
    sign = np.array([1.0, -1.0])[None, :]

    def rhs(d: D) -> Array:
        """+-(value - x_bar_j) of each condition, interleaved."""
        off = values - final(d)[states]
        return np.stack([off, -off], axis=1).ravel()

    return RowBlock(
        "terminal_soft",
        "nonneg",
        2 * len(soft),
        (
            Term(pair, last[states][:, None], sign * scale[states][:, None]),
            Term(pair, slack[:, None], -1.0),
        ),
        rhs=rhs,
    )


def range_block(
    ranges: Sequence[TerminalRow], last: Array, scale: Array, final: Callable[[D], Array]
) -> RowBlock[D]:
    """Two rows per range condition on the last node: lo <= x_j <= hi."""
    states = np.array([t.state for t in ranges], dtype=np.int64)
    hi = np.array([t.hi for t in ranges], dtype=float)
    lo = np.array([t.lo for t in ranges], dtype=float)
    pair = np.arange(len(ranges))[:, None] * 2 + np.array([0, 1])[None, :]

    def rhs(d: D) -> Array:
        """hi - x_bar_j and x_bar_j - lo of each condition, interleaved."""
        xr = final(d)[states]
        return np.stack([hi - xr, xr - lo], axis=1).ravel()

    sign = np.array([1.0, -1.0])[None, :]
    return RowBlock(
        "terminal_range",
        "nonneg",
        2 * len(ranges),
        (Term(pair, last[states][:, None], sign * scale[states][:, None]),),
        rhs=rhs,
    )
