"""What the time-domain subproblem (paper 002 Problem 2) reads each iteration and what it gives
back: grid limits, the linearized data about a reference, the between-node rows, a solution."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worker.solver.transcription.foh_exact import IntervalMaps

Array = np.ndarray


@dataclass(frozen=True)
class GridLimits:
    """Adaptive-grid bounds (nondimensional time): Delta_min, Delta_max, DeltaT_max, and t_f
    when the final time is fixed (None: free, the sum of the intervals a decision variable,
    at most ``final_time_max`` when given)."""

    delta_min: float
    delta_max: float
    delta_trust: float
    final_time: float | None
    final_time_max: float | None = None


@dataclass
class InnerRows:
    """Constraints between the nodes, one row per interval and constraint (path limits, then
    zones).

    Row (k, m): g + c_z . dz_k + c_wm dw_k + c_wp dw_{k+1} + c_s ds_k <= 0: constraint m over
    interval k's samples (the smooth maximum of ``constraints.between_nodes``) carried through
    the exact FOH deviation maps, in nondimensional units. ``c`` holds the four coefficients
    side by side, [c_z | c_wm | c_wp | c_s] (nz + 3 columns for nz states and one control;
    the properties below read that layout, nz + 2 m + 1 columns for m controls); ``worst`` is
    the largest sample value itself, for reports.
    """

    g: Array  # (N, m)
    c: Array  # (N, m, nz + 3)
    worst: Array  # (N, m)

    @property
    def n_states(self) -> int:
        """Number of states the coefficients cover."""
        return int(self.c.shape[2]) - 3

    @property
    def c_z(self) -> Array:
        """Coefficients of dz_k (N, m, nz)."""
        return self.c[:, :, : self.n_states]

    @property
    def c_wm(self) -> Array:
        """Coefficients of dw_k (N, m)."""
        return self.c[:, :, self.n_states]

    @property
    def c_wp(self) -> Array:
        """Coefficients of dw_{k+1} (N, m)."""
        return self.c[:, :, self.n_states + 1]

    @property
    def c_s(self) -> Array:
        """Coefficients of ds_k (N, m)."""
        return self.c[:, :, self.n_states + 2]


@dataclass
class SubproblemData:
    """Everything that changes between iterations: reference, maps, linearized rows, costs.

    Costs in nondimensional state units: linear gradients ``grad_z`` (K, nz) and ``grad_s``
    (N,), and the separable quadratic penalty sum Q (z - c)^2 with ``quad_z``, ``quad_center``
    (K, nz).
    """

    z: Array  # (K, nz)
    w: Array  # (K,), or (K, m) for m controls
    s: Array  # (N,)
    maps: IntervalMaps
    initial: Array  # (n_init,) values of the fixed initial states
    path_g: Array  # (K, m) ln(p / p_max) at the reference
    path_gr: Array  # (K, m)
    path_gv: Array  # (K, m)
    zone_c: Array  # (Z, K) central angle minus zone radius (and margin) at the reference
    zone_clat: Array  # (Z, K)
    zone_clon: Array  # (Z, K)
    grad_z: Array  # (K, nz)
    grad_s: Array  # (N,)
    quad_z: Array  # (K, nz)
    quad_center: Array  # (K, nz)
    inner: InnerRows | None = None
    path_ga: Array | None = None  # (K, m) partials in an angle-of-attack state, per radian
    grad_w: Array | None = None  # like w: the objective's gradient in the rates, when any
    heat_load: float | None = None  # J/m^2 over the FOH substeps, where the objective takes it


@dataclass
class Solution:
    """A subproblem solution mapped back to nodes, rates, interval lengths and slacks."""

    z: Array
    w: Array
    s: Array
    dz: Array  # scaled deviations (K, nz)
    dw: Array  # (K,)
    ds: Array  # (N,)
    soft_slacks: Array
    buffers: Array  # path and zone buffers (virtual control), (n_buffer,)
