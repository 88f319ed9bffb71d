"""The convex subproblem of the time-domain SCP (paper 002 Problem 2) on a fixed sparsity pattern.

Decision vector x = [dz (K x 7), dw (K), ds (N, adaptive grid only), soft-terminal slacks], all
scaled deviations from the reference: z = z_bar + Dz dz, w = w_bar + Dw dw, s = s_bar + Ds ds.
Constraints: the stitched interval dynamics E dz_{k+1} = Phi dz_k + B- dw_k + B+ dw_{k+1} + S ds_k
+ (x_prop - z_bar_{k+1}) (eq. 24, rows divided by the state scale), initial state, terminal
conditions, |sigma| <= sigma_max, |w| <= w_max, the linearized log path limits (eq. 25-26), the
linearized no-fly zones (eq. 27), and on the adaptive grid Delta_min <= s_k <= Delta_max,
|s_k - s_bar_k| <= DeltaT_max and sum s_k = t_f (eq. 11-12). It is a QP (no cones beyond the
nonnegative orthant); the objective's quadratic part is diagonal, plus, for the SQP step, one
convexified Lagrangian Hessian block per interval on (dz_k, dw_k, dw_{k+1}[, ds_k]), the
longitude left out (it enters no rate, so its row and column are zero).

The pattern is built once; ``build`` only writes values into the preallocated data arrays. With
``identity_e`` (exact FOH, E = I) the pattern holds E's diagonal only.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from worker.solver.conic import ConeProblem, ConeSpec, SparseAssembler
from worker.solver.dynamics_bank_state import NZ, SIGMA
from worker.solver.transcription.foh_exact import IntervalMaps
from worker.solver.transcription.foh_hessian import BlockLayout

Array = np.ndarray
R_, TH_, PH_, V_ = 0, 1, 2, 3


@dataclass(frozen=True)
class TerminalRow:
    """A terminal condition on state ``state`` (index into z) in nondimensional units."""

    state: int
    kind: str  # "fixed" | "range" | "soft"
    value: float = 0.0
    lo: float = 0.0
    hi: float = 0.0
    weight: float = 0.0
    virtual: bool = False  # a fixed condition relaxed by an L1-penalized buffer (virtual control)


@dataclass(frozen=True)
class GridLimits:
    """Adaptive-grid bounds (nondimensional time): Delta_min, Delta_max, DeltaT_max, t_f."""

    delta_min: float
    delta_max: float
    delta_trust: float
    final_time: float


@dataclass
class SubproblemData:
    """Everything that changes between iterations: reference, maps, linearized rows, costs.

    Costs in nondimensional state units: linear gradients ``grad_z`` (K, 7) and ``grad_s`` (N,),
    and the separable quadratic penalty sum Q (z - c)^2 with ``quad_z``, ``quad_center`` (K, 7).
    """

    z: Array  # (K, 7)
    w: Array  # (K,)
    s: Array  # (N,)
    maps: IntervalMaps
    initial: Array  # (n_init,) values of the fixed initial states
    path_g: Array  # (K, m) ln(p / p_max) at the reference
    path_gr: Array  # (K, m)
    path_gv: Array  # (K, m)
    zone_c: Array  # (Z, K) central angle minus zone radius (and margin) at the reference
    zone_clat: Array  # (Z, K)
    zone_clon: Array  # (Z, K)
    grad_z: Array  # (K, 7)
    grad_s: Array  # (N,)
    quad_z: Array  # (K, 7)
    quad_center: Array  # (K, 7)
    inner: InnerRows | None = None


@dataclass
class InnerRows:
    """Constraints between the nodes, one row per interval and constraint (path limits, then
    zones).

    Row (k, m): g + c_z . dz_k + c_wm dw_k + c_wp dw_{k+1} + c_s ds_k <= 0: constraint m over
    interval k's samples (the smooth maximum of ``constraints.between_nodes``) carried through
    the exact FOH deviation maps, in nondimensional units. ``c`` holds the four coefficients
    side by side, [c_z | c_wm | c_wp | c_s]; ``worst`` is the largest sample value itself, for
    reports.
    """

    g: Array  # (N, m)
    c: Array  # (N, m, 10)
    worst: Array  # (N, m)

    @property
    def c_z(self) -> Array:
        """Coefficients of dz_k (N, m, 7)."""
        return self.c[:, :, :NZ]

    @property
    def c_wm(self) -> Array:
        """Coefficients of dw_k (N, m)."""
        return self.c[:, :, NZ]

    @property
    def c_wp(self) -> Array:
        """Coefficients of dw_{k+1} (N, m)."""
        return self.c[:, :, NZ + 1]

    @property
    def c_s(self) -> Array:
        """Coefficients of ds_k (N, m)."""
        return self.c[:, :, NZ + 2]


@dataclass
class Solution:
    """A subproblem solution mapped back to nodes, rates, interval lengths and slacks."""

    z: Array
    w: Array
    s: Array
    dz: Array  # scaled deviations (K, 7)
    dw: Array  # (K,)
    ds: Array  # (N,)
    soft_slacks: Array
    buffers: Array  # path and zone buffers (virtual control), (n_buffer,)


class FohSubproblem:
    """Builds Problem 2 of paper 002 as a ``ConeProblem`` with a pattern fixed at construction."""

    def __init__(
        self,
        nodes: int,
        *,
        state_scale: Array,
        rate_scale: float,
        interval_scale: float,
        n_initial: int,
        terminal: list[TerminalRow],
        bank_max: float,
        bank_rate_max: float | None,
        n_limits: int,
        n_zones: int,
        grid: GridLimits | None,
        n_inner_rows: int = 0,
        weight_trust_region: float,
        weight_trust_interval: float,
        weight_buffer: float = 0.0,
        hessian_blocks: bool = False,
        identity_e: bool = False,
    ) -> None:
        self.K = K = nodes
        self.N = N = nodes - 1
        self.Dz = np.asarray(state_scale, dtype=float)
        self.Dw = float(rate_scale)
        self.Ds = float(interval_scale)
        self.n_initial = n_initial
        self.terminal = terminal
        self.soft = [t for t in terminal if t.kind == "soft"]
        self.bank_max = bank_max
        self.bank_rate_max = bank_rate_max
        self.n_limits = n_limits
        self.n_zones = n_zones
        self.n_inner = n_inner_rows
        self.grid = grid
        self.adaptive = grid is not None
        self.w_tr = weight_trust_region
        self.w_tr2 = weight_trust_interval
        self.col_z = np.arange(K * NZ).reshape(K, NZ)
        self.col_w = K * NZ + np.arange(K)
        n = K * NZ + K
        self.col_s = n + np.arange(N) if self.adaptive else np.zeros(0, dtype=int)
        n += self.col_s.size
        self.col_soft = n + np.arange(len(self.soft))
        n += len(self.soft)
        # L1 buffers (virtual control) on the path and zone rows, when weighted
        self.w_buf = weight_buffer
        n_rows_buffered = (n_limits + n_zones) * K + n_inner_rows * N
        self.n_buffer = n_rows_buffered if weight_buffer > 0 else 0
        self.col_buf = n + np.arange(self.n_buffer)
        n += self.n_buffer
        self.n = n
        self._soft_base = np.array([t.weight for t in self.soft])
        self._soft_virtual = np.array([t.virtual for t in self.soft], dtype=bool)
        self._buf_base = weight_buffer
        self.set_virtual_factor(1.0)
        self.n_quad = K * NZ + K + self.col_s.size  # diagonal of P covers z, w and s
        self.hessian_blocks = hessian_blocks
        self.identity_e = identity_e  # E = I (exact FOH): only its diagonal is in the pattern
        cols = [self.col_z[:-1], self.col_w[:-1, None], self.col_w[1:, None]]
        if self.adaptive:
            cols.append(self.col_s[:, None])
        self.block_cols = np.concatenate(cols, axis=1)  # (N, nb) variables of each interval
        self.block_scale = np.r_[self.Dz, self.Dw, self.Dw, [self.Ds] if self.adaptive else []]
        self._structure()

    def set_virtual_factor(self, factor: float) -> None:
        """Scale the weights of the virtual-control buffers (terminal, path, zone) by ``factor``."""
        self.soft_weights = np.where(self._soft_virtual, factor, 1.0) * self._soft_base
        self.w_buf = factor * self._buf_base

    # ------------------------------------------------------------------ structure
    def _structure(self) -> None:
        K, N, Dz = self.K, self.N, self.Dz
        rows: list[Array] = []
        cols: list[Array] = []
        vals: list[Array] = []
        self._blocks: dict[str, slice] = {}
        count = 0

        def add(name: str | None, r: Any, c: Any, v: Any) -> None:
            nonlocal count
            r = np.asarray(r, dtype=np.int64).ravel()
            c = np.asarray(c, dtype=np.int64).ravel()
            rows.append(r)
            cols.append(c)
            vals.append(np.broadcast_to(np.asarray(v, dtype=float), r.shape).ravel())
            if name is not None:
                self._blocks[name] = slice(count, count + r.size)
            count += r.size

        # dynamics: row 7k + i
        k = np.arange(N)[:, None, None]
        i = np.arange(NZ)[None, :, None]
        j = np.arange(NZ)[None, None, :]
        dyn = (NZ * k + i) + 0 * j
        if self.identity_e:
            diag = NZ * np.arange(N)[:, None] + np.arange(NZ)[None, :]
            add("E", diag, self.col_z[1:], 1.0)
        else:
            add("E", dyn, self.col_z[1:][:, None, :] + 0 * i, np.tile(np.eye(NZ).ravel(), N))
        add("Phi", dyn, self.col_z[:-1][:, None, :] + 0 * i, 0.0)
        dyn1 = NZ * np.arange(N)[:, None] + np.arange(NZ)[None, :]
        add("Bm", dyn1, self.col_w[:-1][:, None] + 0 * dyn1, 0.0)
        add("Bp", dyn1, self.col_w[1:][:, None] + 0 * dyn1, 0.0)
        if self.adaptive:
            add("S", dyn1, self.col_s[:, None] + 0 * dyn1, 0.0)
        row = N * NZ
        self.row_initial = row
        add(None, row + np.arange(self.n_initial), self.col_z[0, : self.n_initial], 1.0)
        row += self.n_initial
        self.row_fixed = row
        fixed = [t for t in self.terminal if t.kind == "fixed"]
        for t in fixed:
            add(None, [row], [self.col_z[-1, t.state]], 1.0)
            row += 1
        if self.adaptive:
            self.row_sum = row
            add(None, np.full(N, row), self.col_s, self.Ds)
            row += 1
        self.n_zero = row
        # nonnegative rows: A x <= b
        self.row_bank = row
        add(None, row + np.arange(K), self.col_z[:, SIGMA], Dz[SIGMA])
        add(None, row + K + np.arange(K), self.col_z[:, SIGMA], -Dz[SIGMA])
        row += 2 * K
        if self.bank_rate_max is not None:
            self.row_rate = row
            add(None, row + np.arange(K), self.col_w, self.Dw)
            add(None, row + K + np.arange(K), self.col_w, -self.Dw)
            row += 2 * K
        self.row_path = row
        for m in range(self.n_limits):
            rr = row + m * K + np.arange(K)
            add(f"path_r{m}", rr, self.col_z[:, R_], 0.0)
            add(f"path_v{m}", rr, self.col_z[:, V_], 0.0)
        row += self.n_limits * K
        self.row_zone = row
        for zi in range(self.n_zones):
            rr = row + zi * K + np.arange(K)
            add(f"zone_lat{zi}", rr, self.col_z[:, PH_], 0.0)
            add(f"zone_lon{zi}", rr, self.col_z[:, TH_], 0.0)
        row += self.n_zones * K
        self.row_inner = row
        for m in range(self.n_inner):
            rr = row + m * N + np.arange(N)
            add(f"inner_z{m}", rr[:, None] + 0 * self.col_z[:-1], self.col_z[:-1], 0.0)
            add(f"inner_wm{m}", rr, self.col_w[:-1], 0.0)
            add(f"inner_wp{m}", rr, self.col_w[1:], 0.0)
            if self.adaptive:
                add(f"inner_s{m}", rr, self.col_s, 0.0)
        row += self.n_inner * N
        if self.n_buffer:
            add(None, self.row_path + np.arange(self.n_buffer), self.col_buf, -1.0)
            self.row_buffer = row
            add(None, row + np.arange(self.n_buffer), self.col_buf, -1.0)
            row += self.n_buffer
        if self.adaptive:
            self.row_s = row
            add(None, row + np.arange(N), self.col_s, self.Ds)
            add(None, row + N + np.arange(N), self.col_s, -self.Ds)
            row += 2 * N
        self.row_soft = row
        for si, t in enumerate(self.soft):
            c = self.col_z[-1, t.state]
            add(None, [row, row], [c, self.col_soft[si]], np.array([Dz[t.state], -1.0]))
            add(None, [row + 1, row + 1], [c, self.col_soft[si]], np.array([-Dz[t.state], -1.0]))
            row += 2
        self.row_range = row
        for t in self.terminal:
            if t.kind == "range":
                c = self.col_z[-1, t.state]
                add(None, [row, row + 1], [c, c], np.array([Dz[t.state], -Dz[t.state]]))
                row += 2
        self.m = row
        self.cones = ConeSpec(self.n_zero, self.m - self.n_zero, ())
        self.A_asm = SparseAssembler(np.concatenate(rows), np.concatenate(cols), (self.m, self.n))
        if self.A_asm.has_duplicates:
            raise AssertionError("the subproblem pattern must not repeat a (row, column) pair")
        self._A_data = self.A_asm.assemble_data(np.concatenate(vals))
        pos = self.A_asm.positions
        slots = {name: pos[sl] for name, sl in self._blocks.items()}
        self._slots = slots
        # the values that change, gathered so that each kind is written by one assignment:
        # dynamics [Phi | B- | B+ (| S)] (N, 7, nb), node path rows (K, m), zone rows (Z, K),
        # between-node rows (N, m_inner, nb)
        nb = self.block_cols.shape[1]
        dyn_slots = [slots["Phi"].reshape(N, NZ, NZ), slots["Bm"].reshape(N, NZ, 1)]
        dyn_slots.append(slots["Bp"].reshape(N, NZ, 1))
        if self.adaptive:
            dyn_slots.append(slots["S"].reshape(N, NZ, 1))
        self._slot_dyn = np.concatenate(dyn_slots, axis=2)
        self._slot_path = (
            [np.stack([slots[f"path_{v}{m}"] for m in range(self.n_limits)], axis=1) for v in "rv"]
            if self.n_limits
            else []
        )
        self._slot_zone = (
            [
                np.stack([slots[f"zone_{v}{zi}"] for zi in range(self.n_zones)])
                for v in ("lat", "lon")
            ]
            if self.n_zones
            else []
        )
        inner = []
        for m in range(self.n_inner):
            part = [slots[f"inner_z{m}"].reshape(N, NZ), slots[f"inner_wm{m}"][:, None]]
            part.append(slots[f"inner_wp{m}"][:, None])
            if self.adaptive:
                part.append(slots[f"inner_s{m}"][:, None])
            inner.append(np.concatenate(part, axis=1))
        self._slot_inner = np.stack(inner, axis=1) if inner else None
        inv = 1.0 / Dz
        self._dyn_scale = -self.block_scale[None, :] * inv[:, None]  # (7, nb): rows / Dz_i
        self._e_scale = Dz[None, :] * inv[:, None]
        # The longitude enters no rate (paper 000 eq. 1), so its row and column of every
        # curvature block are zero: the blocks are convexified and stored without it.
        keep = np.array([j for j in range(nb) if j != TH_], dtype=np.int64)
        upper = np.triu_indices(keep.size)
        self.curvature_layout = BlockLayout(
            keep=keep,
            scale=np.ascontiguousarray(self.block_scale[keep], dtype=np.float64),
            rows=upper[0].astype(np.int64),
            cols=upper[1].astype(np.int64),
        )
        self._n_upper = upper[0].size
        diag = np.arange(self.n_quad)
        p_rows, p_cols = [diag], [diag]
        if self.hessian_blocks:  # one upper triangle per interval block; overlaps are summed
            curved_cols = self.block_cols[:, keep]
            a = curved_cols[:, upper[0]].ravel()
            b = curved_cols[:, upper[1]].ravel()
            p_rows.append(np.minimum(a, b))
            p_cols.append(np.maximum(a, b))
        self.P_asm = SparseAssembler(
            np.concatenate(p_rows), np.concatenate(p_cols), (self.n, self.n), upper_triangular=True
        )
        self._scale_rows = np.tile(1.0 / Dz, N)  # dynamics rows divided by the state scale

    # ------------------------------------------------------------------ values
    def build(
        self, d: SubproblemData, curvature: Callable[[], Array | None] | None = None
    ) -> ConeProblem:
        """The subproblem linearized about ``d`` (values only; the pattern never changes).

        ``curvature`` gives the P entries of the curvature blocks (``curvature_layout``; None:
        none). It is called last, once everything else is assembled, so the work that produces
        it can run meanwhile on another thread.
        """
        K, N, Dz, Ds = self.K, self.N, self.Dz, self.Ds
        mp = d.maps
        inv = 1.0 / Dz
        data = self._A_data.copy()
        nb = self.block_cols.shape[1]
        if mp.E is not None:  # the identity otherwise, already in the base values
            if self.identity_e:
                raise ValueError("these maps have an E block; the pattern holds the identity only")
            data[self._slots["E"]] = (mp.E * self._e_scale).ravel()
        data[self._slot_dyn] = mp.jacobian[:, :, :nb] * self._dyn_scale
        if self.n_limits:
            data[self._slot_path[0]] = d.path_gr * Dz[R_]
            data[self._slot_path[1]] = d.path_gv * Dz[V_]
        if self.n_zones:
            data[self._slot_zone[0]] = -d.zone_clat * Dz[PH_]
            data[self._slot_zone[1]] = -d.zone_clon * Dz[TH_]
        if self._slot_inner is not None:
            assert d.inner is not None
            data[self._slot_inner] = d.inner.c[:, :, :nb] * self.block_scale
        A = self.A_asm.matrix(data)

        b = np.zeros(self.m)
        b[: N * NZ] = ((mp.x_prop - d.z[1:]) * inv[None, :]).ravel()
        ni = self.n_initial
        b[self.row_initial : self.row_initial + ni] = (d.initial - d.z[0, :ni]) * inv[:ni]
        row = self.row_fixed
        for t in self.terminal:
            if t.kind == "fixed":
                b[row] = (t.value - d.z[-1, t.state]) * inv[t.state]
                row += 1
        if self.adaptive:
            assert self.grid is not None
            b[self.row_sum] = self.grid.final_time - float(np.sum(d.s))
        sig = d.z[:, SIGMA]
        b[self.row_bank : self.row_bank + K] = self.bank_max - sig
        b[self.row_bank + K : self.row_bank + 2 * K] = self.bank_max + sig
        if self.bank_rate_max is not None:
            b[self.row_rate : self.row_rate + K] = self.bank_rate_max - d.w
            b[self.row_rate + K : self.row_rate + 2 * K] = self.bank_rate_max + d.w
        if self.n_limits:
            b[self.row_path : self.row_path + self.n_limits * K] = -d.path_g.T.ravel()
        if self.n_zones:
            b[self.row_zone : self.row_zone + self.n_zones * K] = d.zone_c.ravel()
        if self.n_inner:
            assert d.inner is not None
            b[self.row_inner : self.row_inner + self.n_inner * N] = -d.inner.g.T.ravel()
        if self.adaptive:
            g = self.grid
            assert g is not None
            b[self.row_s : self.row_s + N] = np.minimum(g.delta_max - d.s, g.delta_trust)
            b[self.row_s + N : self.row_s + 2 * N] = np.minimum(d.s - g.delta_min, g.delta_trust)
        row = self.row_soft
        for t in self.soft:
            off = t.value - d.z[-1, t.state]
            b[row], b[row + 1] = off, -off
            row += 2
        for t in self.terminal:
            if t.kind == "range":
                zr = d.z[-1, t.state]
                b[row], b[row + 1] = t.hi - zr, zr - t.lo
                row += 2

        n_blocks = N * self._n_upper if self.hessian_blocks else 0
        p = np.zeros(self.n_quad + n_blocks)
        pz = p[: K * NZ].reshape(K, NZ)
        pz[:] = 2.0 * self.w_tr + 2.0 * d.quad_z * Dz[None, :] ** 2
        p[K * NZ : K * NZ + K] = 2.0 * self.w_tr
        p[K * NZ + K : self.n_quad] = 2.0 * self.w_tr2
        q = np.zeros(self.n)
        qz = q[: K * NZ].reshape(K, NZ)
        qz[:] = d.grad_z * Dz[None, :] + 2.0 * d.quad_z * (d.z - d.quad_center) * Dz[None, :]
        if self.adaptive:
            q[self.col_s] = d.grad_s * Ds
        q[self.col_soft] = self.soft_weights
        q[self.col_buf] = self.w_buf
        values = curvature() if curvature is not None else None
        if self.hessian_blocks and values is not None:
            p[self.n_quad :] = values
        return ConeProblem(P=self.P_asm.assemble(p), q=q, A=A, b=b, cones=self.cones)

    def unpack(self, x: Array, d: SubproblemData) -> Solution:
        """Nodes, rates, interval lengths and slacks of a subproblem solution ``x``."""
        dz = x[self.col_z]
        dw = x[self.col_w]
        ds = x[self.col_s] if self.adaptive else np.zeros(self.N)
        return Solution(
            z=d.z + dz * self.Dz[None, :],
            w=d.w + dw * self.Dw,
            s=d.s + ds * self.Ds,
            dz=dz,
            dw=dw,
            ds=ds,
            soft_slacks=x[self.col_soft],
            buffers=x[self.col_buf],
        )
