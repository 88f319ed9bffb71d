"""What every method returns to the API layer, whatever its transcription and SCP strategy."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

from worker.solver.scp.history import IterationRecord
from worker.solver.verification import OptimizedTrajectory

MethodStatus = Literal["converged", "max_iterations", "failed", "cancelled", "timed_out"]
IterationSink = Callable[[IterationRecord], None]
StopCheck = Callable[[], bool]


@dataclass
class MethodResult:
    """Status, the optimized trajectory (None when no iteration finished), and the history.

    ``objective_terms`` holds each objective term's value on the final trajectory in SI units
    (J/m^2, s, m/s, deg), keyed by term name.
    """

    status: MethodStatus
    trajectory: OptimizedTrajectory | None
    history: list[IterationRecord]
    conic_solve_s: float
    objective_terms: dict[str, float] = field(default_factory=dict)
    failure_code: str | None = None
    failure_message: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)
