"""Per-iteration convergence record shared by every SCP strategy."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from worker.solver.conic import ConicSolution


@dataclass
class IterationRecord:
    """One SCP iteration, as stored in the job's history and streamed to clients."""

    iteration: int
    cost: float  # the problem's objective on the iterate: SI for one term, else normalized sum
    cost_terms: dict[str, float]
    objective_value: float | None  # the problem's own objective on the new reference, SI units
    max_state_change: dict[str, float]  # per state, SI/degrees
    trust_region_slack: float  # the step's squared length in the method's trust units
    virtual_control_norm: float  # L1 norm of the step's virtual control and buffers (scaled)
    linearization_error: float  # largest dynamics defect the step leaves (trust units)
    nodes_post_corrected: int | None  # energy-scp's shortened (node, state) pairs, else None
    relaxation_gap: float | None  # largest gap of a relaxed control cone, else None
    conic_status: str
    conic_solver: str
    conic_solve_s: float
    conic_setup_s: float
    iteration_wall_s: float
    conic_solver_setup_s: float = 0.0  # inside the solver's own setup/data update (Clarabel)
    subproblem_cost: float | None = None  # the conic subproblem's objective (normalized units)
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return asdict(self)


def solver_fields(solution: ConicSolution) -> dict[str, Any]:
    """The record fields that describe the conic solve of an iteration (its wall time is set
    by the driver when the iteration ends)."""
    return {
        "conic_status": solution.status.value,
        "conic_solver": solution.solver,
        "conic_solve_s": solution.solve_time_s,
        "conic_setup_s": solution.setup_time_s,
        "conic_solver_setup_s": solution.clarabel_setup_s,
        "iteration_wall_s": 0.0,
    }
