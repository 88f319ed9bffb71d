"""The linearization of paper 002's subproblem about a reference: the exact FOH interval maps
(transcription.foh_exact, Theorem 1 / eq. 24; or the trapezoidal rule), the log path limits at
the nodes and between them (eq. 25-26), the no-fly zones (eq. 27) with their penalty windows,
the objective's gradients and, for the SQP step, the curvature of the interval maps
(transcription.foh_hessian)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from app.schemas.methods import FohPtrOptions
from worker.solver.constraints.between_nodes import stack_rows
from worker.solver.constraints.log_path import active_limits, inner_path_rows, path_rows_at
from worker.solver.constraints.no_fly import (
    inner_zone_rows,
    longitude_factor,
    penalty_window,
    zone_distance,
)
from worker.solver.constraints.path_compiled import limit_parameters
from worker.solver.methods.foh_ptr.objective import TimeObjective
from worker.solver.models.layout import BANK_STATE
from worker.solver.problem import EntryProblem
from worker.solver.transcription.foh_data import SubproblemData
from worker.solver.transcription.foh_exact import IntervalMaps, foh_exact
from worker.solver.transcription.foh_hessian import BlockLayout, convexified_curvature
from worker.solver.transcription.time_trapezoid import trapezoid_maps

Array = np.ndarray


class Linearizer:
    """Builds the per-iteration ``SubproblemData`` (maps, path rows, zone rows, costs) of the
    bank-state model (``layout.BANK_STATE``)."""

    layout = BANK_STATE

    def __init__(self, problem: EntryProblem, options: FohPtrOptions, scale: Array) -> None:
        self.problem = problem
        self.options = options
        self.scale = scale
        self.limits = active_limits(problem)
        self.zones = problem.no_fly_zones
        self.margin = 0.0
        fixed_bank = problem.initial_bank
        self.initial = (
            np.r_[problem.y0, fixed_bank] if fixed_bank is not None else problem.y0.copy()
        )
        self.objective: TimeObjective | None = None
        self.windows: list[list[int]] = []
        self.zone_clearance: list[float] = []
        self.inner_on = bool(
            options.intersample_constraints
            and options.discretization == "exact_foh"
            and options.foh_substeps > 1
            and (self.limits or self.zones)
        )
        self.inner_exact = options.intersample_smooth_max == "exact"  # value at the worst sample
        self.inner_ratio = np.zeros(len(self.limits))
        self.path_parameters = limit_parameters(problem, self.limits)  # None: numpy rows
        self.second_order = bool(options.second_order)  # the schema allows it with exact_foh only
        self.difference_steps: Array | None = None  # set once the subproblem's scales are known
        self.blocks: BlockLayout | None = None  # where the curvature goes in the subproblem's P

    def maps(self, z: Array, w: Array, s: Array) -> IntervalMaps:
        p, o = self.problem, self.options
        if o.discretization == "trapezoid":
            return trapezoid_maps(z, w, s, p.forces, p.omega)
        return foh_exact(z, w, s, p.forces, p.omega, o.foh_substeps, samples=self.inner_on)

    def curvature(self, z: Array, w: Array, s: Array, multipliers: Array | None) -> Array | None:
        """The P entries of the convexified Lagrangian curvature of the interval maps about the
        reference (z, w, s) (``foh_hessian.convexified_curvature``), or None.

        ``multipliers`` (N, 7): the last subproblem's multipliers of the dynamics rows, in
        nondimensional state units. None without them, without ``second_order``, or when a
        perturbed integration is not finite (the step is then first-order).
        """
        if multipliers is None or not self.second_order or self.blocks is None:
            return None
        assert self.difference_steps is not None
        p = self.problem
        return convexified_curvature(
            z,
            w,
            s,
            p.forces,
            p.omega,
            -multipliers,  # the rows read x_{k+1} - Phi_k(v_k): Phi_k enters with a minus
            self.difference_steps,
            self.options.second_order_substeps,
            self.blocks,
        )

    def report(self) -> dict[str, Any]:
        """The last linearization's between-node path ratios and zone clearances, for the
        history (``IterationRecord.extra``)."""
        between = (
            {name: float(self.inner_ratio[j]) for j, name in enumerate(self.limits)}
            if self.inner_on and self.limits
            else {}
        )
        return {
            "path_ratio_between_nodes": between,
            "no_fly_zone_clearance_deg": list(self.zone_clearance),
            "no_fly_zone_window_nodes": [list(wd) for wd in self.windows],
        }

    def data(self, z: Array, w: Array, s: Array) -> tuple[SubproblemData, Array]:
        """Subproblem data about (z, w, s), without the curvature (``curvature``), and the
        path-limit ratios at the nodes (K, m)."""
        p, o = self.problem, self.options
        k, nz = z.shape
        mp = self.maps(z, w, s)
        inner = None
        if self.inner_on:
            samples = mp.samples
            assert samples is not None
            n, j = samples.x.shape[:2]
            # one evaluation at every sample and the last node: sample 0 of interval k is node k
            r = np.concatenate([samples.x[..., 0].ravel(), z[-1:, 0]])
            v = np.concatenate([samples.x[..., 3].ravel(), z[-1:, 3]])
            at_samples = path_rows_at(p, r, v, self.path_parameters)
            rows = at_samples.take(np.arange(0, n * j + 1, j))  # sample 0s, then the last node
            parts = []
            if self.limits:
                parts.append(
                    inner_path_rows(
                        at_samples.take(slice(0, n * j)),
                        samples,
                        o.intersample_width_log,
                        exact=self.inner_exact,
                    )
                )
                self.inner_ratio = np.exp(np.max(parts[0].worst, axis=0))
            if self.zones:
                parts.append(
                    inner_zone_rows(
                        self.zones,
                        samples,
                        math.radians(o.intersample_width_zone_deg),
                        exact=self.inner_exact,
                        margin=self.margin,
                    )
                )
            inner = stack_rows(parts)
        else:
            rows = path_rows_at(p, z[:, 0], z[:, 3], self.path_parameters)
        if self.objective is None:
            self.objective = TimeObjective(p, self.scale, z, s)
        grad_z, grad_s = self.objective.gradients(z, s)
        quad = np.zeros((k, nz))
        quad_c = np.zeros((k, nz))
        if rows.names and o.weight_nonlinear > 0:
            quad[:, 3] = o.weight_nonlinear / z[:, 3] ** 2  # eq. 26: (V - V_bar)^2 / V_bar^2
            quad_c[:, 3] = z[:, 3]
        nzone = len(self.zones)
        zc = np.zeros((nzone, k))
        zlat = np.zeros((nzone, k))
        zlon = np.zeros((nzone, k))
        weighted_c = np.zeros((k, nz))
        self.windows = []
        self.zone_clearance = []
        for i, zone in enumerate(self.zones):
            rows_z = zone_distance(z[:, 2], z[:, 1], zone)
            clearance = rows_z.c - zone.radius
            zc[i] = clearance - self.margin
            zlat[i] = rows_z.c_lat
            zlon[i] = rows_z.c_lon
            self.zone_clearance.append(math.degrees(float(np.min(clearance))))
            engaged = float(np.min(clearance)) <= math.radians(o.no_fly_zone_engage_deg)
            if engaged and o.weight_no_fly_zone > 0:
                mask = penalty_window(clearance, o.no_fly_zone_window)
                self.windows.append([int(j) for j in np.flatnonzero(mask)])
                wz = o.weight_no_fly_zone / zone.radius**2
                coslat = longitude_factor(zone)
                quad[mask, 2] += wz
                weighted_c[mask, 2] += wz * zone.latitude
                quad[mask, 1] += wz * coslat**2
                weighted_c[mask, 1] += wz * coslat**2 * zone.longitude
            else:
                self.windows.append([])
        if any(self.windows):  # an engaged zone pulls its window toward its centre
            for j in (1, 2):
                on = quad[:, j] > 0
                quad_c[on, j] = weighted_c[on, j] / quad[on, j]
        data = SubproblemData(
            z=z,
            w=w,
            s=s,
            maps=mp,
            initial=self.initial,
            path_g=rows.g,
            path_gr=rows.g_r,
            path_gv=rows.g_v,
            zone_c=zc,
            zone_clat=zlat,
            zone_clon=zlon,
            grad_z=grad_z,
            grad_s=grad_s,
            quad_z=quad,
            quad_center=quad_c,
            inner=inner,
        )
        return data, rows.ratio


def finite(data: SubproblemData) -> bool:
    """Whether the linearization is usable (a long step can leave the atmosphere model)."""
    mp = data.maps
    parts = [mp.x_prop, mp.jacobian, data.path_g]
    if data.inner is not None:
        parts.append(data.inner.g)
    return all(bool(np.all(np.isfinite(a))) for a in parts)


def defect(data: SubproblemData, scale: Array) -> tuple[Array, float]:
    """How far the reference nodes are from their own propagation: the largest gap per state
    (nondimensional) and overall in scaled units. It judges the step that made the reference."""
    by_state = np.max(np.abs(data.maps.x_prop - data.z[1:]), axis=0)
    return by_state, float(np.max(by_state / scale))
