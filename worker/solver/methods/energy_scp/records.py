"""The history record of one iteration of paper 000's method: the step, its cost terms, its
size per state, the post-corrected nodes and the relaxation gap of the control cone."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from worker.solver.conic import ConicSolution
from worker.solver.models.layout import ENERGY
from worker.solver.objective_weights import weighted_sum
from worker.solver.scp.history import IterationRecord, solver_fields

if TYPE_CHECKING:
    from worker.solver.methods.energy_scp.method import EnergyScp

Array = np.ndarray


def iteration_record(
    method: EnergyScp,
    iteration: int,
    sub: Any,
    solution: ConicSolution,
    values: dict[str, float],
    lin_err: Array,
    corrected: Array,
) -> tuple[IterationRecord, float]:
    """The record of the unpacked solution ``sub`` and its virtual-control norm."""
    p, o, tr = method.problem, method.options, method.tr
    dynamic_vc = (
        float(np.sum(np.abs(sub.virtual_control))) if sub.virtual_control is not None else 0.0
    )
    vc_norm = dynamic_vc
    # fixed terminal conditions held by an exact penalty: their miss, in trust units, is
    # virtual control that must vanish (as PTR's terminal buffers, paper 002 sec. IV)
    virtual = np.array([t.virtual for t in tr.soft], dtype=bool)
    if np.any(virtual):
        units = method.scale[[t.state for t in tr.soft if t.virtual]]
        vc_norm += float(np.sum(sub.soft_slacks[virtual] / units))
    soft_weights = np.array([t.weight for t in tr.soft if not t.virtual])
    tr_slack = float(np.sum(sub.dx_scaled**2))
    weighted = weighted_sum(values, {t.name: t.weight for t in p.objective})
    record = IterationRecord(
        iteration=iteration,
        cost=(
            next(iter(values.values()))
            if len(values) == 1
            else (weighted if weighted is not None else float("nan"))
        ),
        subproblem_cost=float(solution.objective if solution.objective is not None else np.nan),
        cost_terms={
            **{f"objective:{n}": v for n, v in values.items()},
            "soft_terminal": float(np.dot(soft_weights, sub.soft_slacks[~virtual]))
            if soft_weights.size
            else 0.0,
            "trust_region": float(method.trust.weight * tr_slack),
            "virtual_control": float(
                np.dot([t.weight for t in tr.soft if t.virtual], sub.soft_slacks[virtual])
                + o.weight_virtual_control * dynamic_vc
            ),
        },
        objective_value=next(iter(values.values())) if len(values) == 1 else None,
        max_state_change=ENERGY.deltas_to_si(method.change, p.scales),
        trust_region_slack=tr_slack,
        virtual_control_norm=vc_norm,
        linearization_error=float(np.max(lin_err)),
        nodes_post_corrected=int(np.count_nonzero(np.any(corrected, axis=1))),
        relaxation_gap=float(np.max(1.0 - np.linalg.norm(sub.u, axis=1))),
        **solver_fields(solution),
        extra={"weight_trust_region": method.trust.weight},
    )
    return record, vc_norm
