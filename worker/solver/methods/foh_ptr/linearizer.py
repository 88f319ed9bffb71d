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
from worker.solver.constraints.log_path import (
    LogPathRows,
    active_limits,
    inner_path_rows,
    log_path_rows,
    path_rows_at,
)
from worker.solver.constraints.no_fly import (
    inner_zone_rows,
    longitude_factor,
    penalty_window,
    zone_distance,
)
from worker.solver.constraints.path_compiled import limit_parameters
from worker.solver.methods.foh_ptr.objective import TimeObjective
from worker.solver.problem import EntryProblem
from worker.solver.transcription.foh_data import SubproblemData
from worker.solver.transcription.foh_exact import IntervalMaps, foh_exact
from worker.solver.transcription.foh_hessian import BlockLayout, convexified_curvature
from worker.solver.transcription.foh_model import foh_model
from worker.solver.transcription.time_trapezoid import trapezoid_maps

Array = np.ndarray


class Linearizer:
    """Builds the per-iteration ``SubproblemData`` (maps, path rows, zone rows, costs) of the
    problem's FOH model (``foh_model``: bank state, or bank and angle of attack)."""

    def __init__(self, problem: EntryProblem, options: FohPtrOptions, scale: Array) -> None:
        self.problem = problem
        self.options = options
        self.scale = scale
        self.model = foh_model(problem)
        self.layout = self.model.layout
        self.limits = active_limits(problem)
        self.zones = problem.no_fly_zones
        self.margin = 0.0
        fixed = [(j, v) for j, v in enumerate(problem.y0)]
        if problem.initial_bank is not None:
            fixed.append((self.model.bank, problem.initial_bank))
        if self.model.alpha is not None and problem.initial_alpha is not None:
            fixed.append((self.model.alpha, problem.initial_alpha))
        self.initial_states = np.array([j for j, _ in fixed], dtype=np.int64)
        self.initial = np.array([v for _, v in fixed], dtype=float)
        self.objective: TimeObjective | None = None
        self.windows: list[list[int]] = []
        self.zone_clearance: list[float] = []
        self.inner_on = bool(
            options.intersample_constraints
            and options.discretization == "exact_foh"
            and options.foh_substeps > 1
            and (self.limits or self.zones)
        )
        # the heat load is integrated over the FOH substeps, not the nodes' trapezoid
        self.sampled_heat = options.discretization == "exact_foh" and any(
            t.name == "min_heat_load" for t in problem.objective
        )
        self.inner_exact = options.intersample_smooth_max == "exact"  # value at the worst sample
        self.inner_ratio = np.zeros(len(self.limits))
        alpha_state = self.model.alpha is not None  # the compiled rows know no alpha state
        self.path_parameters = None if alpha_state else limit_parameters(problem, self.limits)
        self.second_order = bool(options.second_order)  # the schema allows it with exact_foh only
        self.difference_steps: Array | None = None  # set once the subproblem's scales are known
        self.blocks: BlockLayout | None = None  # where the curvature goes in the subproblem's P

    def maps(self, z: Array, w: Array, s: Array) -> IntervalMaps:
        p, o = self.problem, self.options
        if o.discretization == "trapezoid":
            return trapezoid_maps(z, w, s, p.forces, p.omega)
        return foh_exact(
            z,
            w,
            s,
            p.forces,
            p.omega,
            o.foh_substeps,
            samples=self.inner_on or self.sampled_heat,
            dynamics=self.model.dynamics,
        )

    def rows_at(self, x: Array) -> LogPathRows:
        """The log path rows at states ``x`` (..., nz): at their own angle of attack when it is a
        state (partials in it per radian), else on the schedule."""
        p, a = self.problem, self.model.alpha
        r, v = x[..., 0].ravel(), x[..., 3].ravel()
        if a is None:
            return path_rows_at(p, r, v, self.path_parameters)
        alpha_deg = x[..., a].ravel() * self.model.unit
        return log_path_rows(p, r, v, p.forces.terms(r, v, alpha_deg), alpha_state=True)

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
            dynamics=self.model.dynamics,
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
            points = np.concatenate([samples.x.reshape(n * j, nz), z[-1:]])
            at_samples = self.rows_at(points)
            rows = at_samples.take(np.arange(0, n * j + 1, j))  # sample 0s, then the last node
            parts = []
            if self.limits:
                parts.append(
                    inner_path_rows(
                        at_samples.take(slice(0, n * j)),
                        samples,
                        o.intersample_width_log,
                        exact=self.inner_exact,
                        alpha=self.model.alpha,
                        unit=self.model.unit,
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
            rows = self.rows_at(z)
        if self.objective is None:
            self.objective = TimeObjective(p, self.scale, z, s, self.model.alpha, self.model.unit)
        heat_load, heat_block = None, None
        if self.sampled_heat:  # once per reference: its value and its gradient
            assert mp.samples is not None
            heat_load, heat_block = self.objective.sampled_heat(mp.samples, s)
        grad_z, grad_s, grad_w = self.objective.gradients(
            z, s, heat_block=heat_block, w_shape=w.shape
        )
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
            path_ga=None if rows.g_a is None else rows.g_a * self.model.unit,
            grad_w=grad_w,
            heat_load=heat_load,
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
