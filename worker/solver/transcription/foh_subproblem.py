"""The convex subproblem of the time-domain SCP (paper 002 Problem 2) on a fixed sparsity pattern.

Decision vector x = [dz (K x nz), dw (K, or K x m for m controls), ds (N, adaptive grid only),
soft-terminal slacks, buffers], all scaled deviations from the reference: z = z_bar + Dz dz,
w = w_bar + Dw dw, s = s_bar + Ds ds. The rows are declared once as blocks (``foh_rows``), the
objective in ``foh_cost``. It is a QP (no cones beyond the nonnegative orthant). The pattern is
built once; ``build`` only writes values. With ``identity_e`` (exact FOH, E = I) the pattern
holds E's diagonal only.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from worker.solver.conic import ConeProblem
from worker.solver.models.layout import BANK_STATE, StateLayout
from worker.solver.transcription.foh_cost import FohCost
from worker.solver.transcription.foh_data import GridLimits, Solution, SubproblemData
from worker.solver.transcription.foh_rows import row_blocks
from worker.solver.transcription.rows import Columns, RowSystem
from worker.solver.transcription.terminal import TerminalRow

Array = np.ndarray
_INDEXED_STATES = ("altitude_m", "longitude_deg", "latitude_deg", "velocity_m_s", "bank_deg")


@dataclass(frozen=True)
class AlphaBounds:
    """An alpha state's place and limits in its own units (radians of angle of attack, or a
    polar's normalized lift; the rate per nondimensional time, None: unbounded)."""

    index: int
    low: float
    high: float
    rate_max: float | None


class FohSubproblem:
    """Builds Problem 2 of paper 002 as a ``ConeProblem`` with a pattern fixed at construction.

    ``layout`` names the states of z (any model carrying altitude, longitude, latitude, speed and
    bank); ``state_scale`` holds one scale per state. ``controls``: rates per node (2 with an
    alpha state, the bank's first); ``initial_states``: the states fixed at the first node
    (default the first ``n_initial``); ``alpha``: the alpha state's range and rate rows.
    """

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
        weight_trust_final_time: float | None = None,
        weight_buffer: float = 0.0,
        hessian_blocks: bool = False,
        identity_e: bool = False,
        layout: StateLayout = BANK_STATE,
        bank_min: float | None = None,
        controls: int = 1,
        initial_states: Array | None = None,
        alpha: AlphaBounds | None = None,
    ) -> None:
        self.K = K = nodes
        self.N = N = nodes - 1
        self.layout = layout
        self.nz = nz = layout.size
        self.Dz = np.asarray(state_scale, dtype=float)
        if self.Dz.shape != (nz,):
            raise ValueError(f"state_scale needs {nz} entries for the {layout.name} layout")
        self.state_index = tuple(layout.index(name) for name in _INDEXED_STATES)
        self.controls = controls
        self.Dw = float(rate_scale)
        self.Ds = float(interval_scale)
        self.n_initial = n_initial
        self.initial_states = (
            np.arange(n_initial) if initial_states is None else np.asarray(initial_states)
        )
        self.alpha = alpha
        self.terminal = terminal
        self.soft = [t for t in terminal if t.kind == "soft"]
        self.bank_max = bank_max
        self.bank_min = -bank_max if bank_min is None else bank_min
        self.bank_rate_max = bank_rate_max
        self.n_limits = n_limits
        self.n_zones = n_zones
        self.n_inner = n_inner_rows
        self.grid = grid
        self.adaptive = grid is not None
        self.w_tr = weight_trust_region
        self.w_tr2 = weight_trust_interval
        self.free_final_time = grid is not None and grid.final_time is None
        self.w_trT = (
            weight_trust_interval if weight_trust_final_time is None else weight_trust_final_time
        )
        self.hessian_blocks = hessian_blocks
        self.identity_e = identity_e  # E = I (exact FOH): only its diagonal is in the pattern
        # L1 buffers (virtual control) on the path, zone and between-node rows, when weighted
        n_buffered = (n_limits + n_zones) * K + n_inner_rows * N
        self.n_buffer = n_buffered if weight_buffer > 0 else 0
        self.columns = cols = Columns()
        self.col_z = cols.add("z", K, nz)
        self.col_w = cols.add("w", K) if controls == 1 else cols.add("w", K, controls)
        self.col_bank_rate = self.col_w if controls == 1 else self.col_w[:, 0]
        self.col_s = cols.add("s", N if self.adaptive else 0)
        self.col_soft = cols.add("soft", len(self.soft))
        self.col_buf = cols.add("buffer", self.n_buffer)
        self.n = cols.n
        self.w_buf = weight_buffer
        self._soft_base = np.array([t.weight for t in self.soft])
        self._soft_virtual = np.array([t.virtual for t in self.soft], dtype=bool)
        self._buf_base = weight_buffer
        self.set_virtual_factor(1.0)
        w_cols = self.col_w.reshape(K, controls)
        block = [self.col_z[:-1], w_cols[:-1], w_cols[1:]]
        if self.adaptive:
            block.append(self.col_s[:, None])
        self.block_cols = np.concatenate(block, axis=1)  # (N, nb) variables of each interval
        rates = np.full(2 * controls, self.Dw)
        self.block_scale = np.r_[self.Dz, rates, [self.Ds] if self.adaptive else []]
        self.rows = RowSystem(row_blocks(self), self.n)
        if self.rows.assembler.has_duplicates:
            raise AssertionError("the subproblem pattern must not repeat a (row, column) pair")
        self.A_asm = self.rows.assembler
        self.cones = self.rows.cones
        self.m = self.rows.m
        self.n_zero = self.cones.n_zero
        self.cost = FohCost(self)
        self.curvature_layout = self.cost.curvature_layout
        self.n_quad = self.cost.n_quad
        self.P_asm = self.cost.P_asm

    def set_virtual_factor(self, factor: float) -> None:
        """Scale the weights of the virtual-control buffers (terminal, path, zone) by ``factor``."""
        self.soft_weights = np.where(self._soft_virtual, factor, 1.0) * self._soft_base
        self.w_buf = factor * self._buf_base

    def build(
        self, d: SubproblemData, curvature: Callable[[], Array | None] | None = None
    ) -> ConeProblem:
        """The subproblem linearized about ``d`` (values only; the pattern never changes).

        ``curvature`` gives the P entries of the curvature blocks (``curvature_layout``; None:
        none). It is called last, once everything else is assembled, so the work that produces
        it can run meanwhile on another thread.
        """
        if self.identity_e and d.maps.E is not None:
            raise ValueError("these maps have an E block; the pattern holds the identity only")
        A = self.rows.A(d)
        b = self.rows.b(d)
        p = self.cost.diagonal(d)
        q = self.cost.q(d)
        values = curvature() if curvature is not None else None
        return ConeProblem(P=self.cost.P(p, values), q=q, A=A, b=b, cones=self.cones)

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
