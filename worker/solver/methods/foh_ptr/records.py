"""The history record of one iteration of paper 002's method: the step, its cost terms, its
size per state, the virtual control it spent and what the linearization saw."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from worker.solver.conic import ConicSolution
from worker.solver.methods.foh_ptr.linearizer import defect
from worker.solver.scp.history import IterationRecord, solver_fields
from worker.solver.transcription.foh_data import SubproblemData

if TYPE_CHECKING:
    from worker.solver.methods.foh_ptr.method import FohIterate, FohPtr

Array = np.ndarray


def iteration_record(
    method: FohPtr,
    iteration: int,
    reference: FohIterate,
    new: Any,
    data: SubproblemData,
    candidate: SubproblemData,
    ratio: Array,
    report: dict[str, Any],
    values: dict[str, float],
    solution: ConicSolution,
    discretization_s: float,
    step: Array,
) -> tuple[IterationRecord, bool, float]:
    """The record of the step ``new`` (the unpacked solution) made about ``reference`` by the
    subproblem of ``data`` (``candidate``: the linearization about the step's nodes, whose
    defect is the step's); whether the step is below the stop tolerances, and its
    virtual-control norm (scaled units)."""
    o, sub, lin = method.options, method.sub, method.lin
    sc = method.problem.scales
    z, s = reference.z, reference.s
    change = np.max(np.abs(new.z - z), axis=0)
    change_s = float(np.max(np.abs(new.s - s))) if s.size else 0.0
    w_tr = method.trust.weight
    tr_slack = float(np.dot(step, step))
    quad, center = data.quad_z, data.quad_center
    nl_pen = float(np.sum(quad[:, 3] * (new.z[:, 3] - z[:, 3]) ** 2))
    zone_pen = float(np.sum(quad[:, 1:3] * (new.z[:, 1:3] - center[:, 1:3]) ** 2))
    virtual = np.array([t.virtual for t in sub.soft], dtype=bool)  # terminal buffers
    soft_weights = np.array([t.weight for t in sub.soft if not t.virtual])
    virtual_unit = 1.0 / method.scale[[t.state for t in sub.soft if t.virtual]]
    soft = float(np.dot(soft_weights, new.soft_slacks[~virtual]))
    vc_norm = float(np.sum(new.soft_slacks[virtual] * virtual_unit) + np.sum(new.buffers))
    t_nodes = np.concatenate([[0.0], np.cumsum(new.s)]) * sc.time_s
    record = IterationRecord(
        iteration=iteration,
        cost=float(solution.objective if solution.objective is not None else np.nan),
        cost_terms={
            **{f"objective:{n}": v for n, v in values.items()},
            "trust_region": w_tr * tr_slack,
            "trust_interval": sub.cost.interval_trust(new.ds),
            "nonlinear_path": nl_pen,
            "no_fly_zone": zone_pen,
            "soft_terminal": soft,
            "virtual_control": o.weight_virtual_control * vc_norm,
        },
        objective_value=next(iter(values.values())) if len(values) == 1 else None,
        max_state_change=lin.layout.deltas_to_si(change, sc),
        trust_region_slack=tr_slack,
        virtual_control_norm=vc_norm,
        linearization_error=defect(candidate, method.scale)[1],
        nodes_post_corrected=None,
        relaxation_gap=None,
        **solver_fields(solution),
        extra={
            "max_interval_change_s": change_s * sc.time_s,
            "interval_s_min": float(np.min(new.s) * sc.time_s),
            "interval_s_max": float(np.max(new.s) * sc.time_s),
            "path_ratio_at_nodes": {
                name: float(np.max(ratio[:, j])) for j, name in enumerate(lin.limits)
            },
            **report,
            "discretization_s": discretization_s,
            "second_order_step": method.second_order,
            "weight_trust_region": w_tr,
            "node_times_s": t_nodes.tolist(),
        },
    )
    bank = method.model.bank
    authority = bank_authority(method, z, new.z)
    tested = change.copy()  # the bank's change only where it turns a lift worth the name
    tested[bank] = float(np.max(np.abs(new.z[authority, bank] - z[authority, bank]), initial=0.0))
    small = bool(np.all(tested <= method.tol_z) and change_s <= method.tol_s)
    return record, small, vc_norm


def bank_authority(method: FohPtr, z: Array, z_new: Array) -> Array:
    """The nodes whose dynamic pressure, on the reference or the step, is at least
    ``stop_tolerance.bank_dynamic_pressure_fraction`` of the step's peak: there the bank turns
    a lift (proportional to the dynamic pressure) that moves the states; elsewhere its swings
    are a flat direction of the subproblem and the state tolerances judge the step."""
    fraction = method.options.stop_tolerance.bank_dynamic_pressure_fraction
    if fraction <= 0.0:
        return np.ones(z.shape[0], dtype=bool)
    sc = method.problem.scales
    atmosphere = method.problem.forces.atmosphere
    q = [atmosphere.density((x[:, 0] - 1.0) * sc.radius_m)[0] * x[:, 3] ** 2 for x in (z, z_new)]
    q_node = np.maximum(q[0], q[1])  # proportional to the dynamic pressure (same factor)
    return np.asarray(q_node >= fraction * float(np.max(q[1])))
