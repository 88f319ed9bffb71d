"""Terminal rows of both methods (to be replaced by transcription.terminal)."""

from __future__ import annotations

from typing import Any, Literal

import numpy as np

from worker.solver.models.layout import StateLayout
from worker.solver.problem import EntryProblem


def terminal_rows(
    problem: EntryProblem,
    layout: StateLayout,
    *,
    fixed: Literal["hard", "virtual"],
    virtual_weight: float = 0.0,
    trust_units: np.ndarray | None = None,
) -> list[Any]:
    """Terminal rows as the two transcriptions take them today."""
    if fixed == "virtual":
        from worker.solver.transcription.foh_subproblem import TerminalRow as FohRow

        assert trust_units is not None
        rows: list[Any] = []
        for j, key in layout.terminal_states():
            t = problem.terminal[key]
            if t.kind == "fixed":
                w = virtual_weight / trust_units[j]
                rows.append(FohRow(j, "soft", value=float(t.value or 0.0), weight=w, virtual=True))
            elif t.kind == "soft":
                rows.append(FohRow(j, "soft", value=float(t.value or 0.0), weight=t.weight))
            elif t.kind == "range":
                rows.append(FohRow(j, "range", lo=float(t.lo or 0.0), hi=float(t.hi or 0.0)))
        return rows
    from worker.solver.transcription.energy_trapezoid import TerminalRow as ERow

    out: list[Any] = []
    for j, key in layout.terminal_states():
        t = problem.terminal[key]
        if t.kind == "fixed":
            out.append(ERow(j, "fixed", value=float(t.value or 0.0)))
        elif t.kind == "soft":
            out.append(ERow(j, "soft", value=float(t.value or 0.0), weight=t.weight))
        elif t.kind == "range":
            out.append(ERow(j, "range", lo=float(t.lo or 0.0), hi=float(t.hi or 0.0)))
    return out
