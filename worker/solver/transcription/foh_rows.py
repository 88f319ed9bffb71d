"""The row blocks of the time-domain subproblem (paper 002 Problem 2), each declared once.

Equalities: the stitched interval dynamics E dz_{k+1} = Phi dz_k + B- dw_k + B+ dw_{k+1} + S ds_k
+ (x_prop - z_bar_{k+1}) (eq. 24, rows divided by the state scale), the initial state, the fixed
terminal states and, on the adaptive grid with a fixed final time, sum s_k = t_f (eq. 12); with
a free final time the sum is free (time dilation per interval), at most t_f,max. Nonnegative rows:
|sigma| <= sigma_max at the nodes and where the bank turns between them, |w| <= w_max, the
linearized log path limits (eq. 25-26), the linearized no-fly zones (eq. 27), the between-node
rows, their L1 buffers, Delta_min <= s_k <= Delta_max with |s_k - s_bar_k| <= DeltaT_max
(eq. 11), then the soft and range terminal rows.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from worker.solver.transcription.foh_data import SubproblemData
from worker.solver.transcription.rows import RowBlock, Term
from worker.solver.transcription.terminal import range_block, soft_block

if TYPE_CHECKING:
    from worker.solver.transcription.foh_subproblem import FohSubproblem

Array = np.ndarray
Block = RowBlock[SubproblemData]


def _inner(d: SubproblemData) -> Array:
    """The between-node coefficients of ``d`` (present whenever the pattern has such rows)."""
    assert d.inner is not None
    return d.inner.c


def _inner_g(d: SubproblemData) -> Array:
    """The between-node constraint values of ``d``."""
    assert d.inner is not None
    return d.inner.g


def equality_blocks(sub: FohSubproblem) -> list[Block]:
    """Dynamics, initial state, fixed terminal states and (adaptive grid) the final time."""
    N, nz, nb = sub.N, sub.nz, sub.block_cols.shape[1]
    inv = 1.0 / sub.Dz
    dyn_scale = -sub.block_scale[None, :] * inv[:, None]  # (nz, nb): rows / Dz_i
    e_scale = sub.Dz[None, :] * inv[:, None]
    node_row = nz * np.arange(N)[:, None] + np.arange(nz)[None, :]  # row nz k + i
    if sub.identity_e:  # exact FOH: E = I, only its diagonal is in the pattern
        e_term = Term[SubproblemData](node_row, sub.col_z[1:], 1.0)
    else:
        e_term = Term(
            node_row[:, :, None],
            sub.col_z[1:][:, None, :],
            np.broadcast_to(np.eye(nz), (N, nz, nz)),
            update=lambda d: None if d.maps.E is None else d.maps.E * e_scale,
        )
    blocks = [
        Block(
            "dynamics",
            "zero",
            N * nz,
            (
                e_term,
                Term(  # [Phi | B- | B+ (| S)] on the interval's variables
                    node_row[:, :, None],
                    sub.block_cols[:, None, :],
                    update=lambda d: d.maps.jacobian[:, :, :nb] * dyn_scale,
                ),
            ),
            rhs=lambda d: ((d.maps.x_prop - d.z[1:]) * inv[None, :]).ravel(),
        ),
    ]
    ni, fixed_at = sub.n_initial, sub.initial_states
    blocks.append(
        Block(
            "initial",
            "zero",
            ni,
            (Term(np.arange(ni), sub.col_z[0, fixed_at], 1.0),),
            rhs=lambda d: (d.initial - d.z[0, fixed_at]) * inv[fixed_at],
        )
    )
    fixed = [t for t in sub.terminal if t.kind == "fixed"]
    states = np.array([t.state for t in fixed], dtype=np.int64)
    values = np.array([t.value for t in fixed], dtype=float)
    blocks.append(
        Block(
            "terminal_fixed",
            "zero",
            len(fixed),
            (Term(np.arange(len(fixed)), sub.col_z[-1, states], 1.0),),
            rhs=lambda d: (values - d.z[-1, states]) * inv[states],
        )
    )
    if sub.grid is not None and sub.grid.final_time is not None:
        final_time = sub.grid.final_time
        blocks.append(
            Block(
                "final_time",
                "zero",
                1,
                (Term(np.zeros(N, dtype=np.int64), sub.col_s, sub.Ds),),
                rhs=lambda d: final_time - float(np.sum(d.s)),
            )
        )
    return blocks


def bound_block(
    name: str,
    cols: Array,
    scale: float,
    bound: float,
    value: Callable[[SubproblemData], Array],
    lower: float | None = None,
) -> Block:
    """lower <= v <= bound at every node (lower = -bound by default) for the variable on
    ``cols`` (scaled by ``scale``; ``value(d)`` its reference): rows scale dv <= bound - v_bar,
    then -scale dv <= v_bar - lower."""
    K = cols.size
    rows = np.arange(K)
    low = -bound if lower is None else lower

    def rhs(d: SubproblemData) -> Array:
        """bound - v_bar at every node, then v_bar - lower."""
        v = value(d)
        return np.concatenate([bound - v, v - low])

    return Block(
        name, "nonneg", 2 * K, (Term(rows, cols, scale), Term(K + rows, cols, -scale)), rhs=rhs
    )


def bank_vertex(z_bank: Array, w: Array, s: Array) -> tuple[Array, Array, Array, Array]:
    """Where the first-order-hold bank of each interval turns, and its linearization there.

    With the bank rate linear between the nodes, the bank over interval k is the quadratic
    sigma(tau) = sigma_k + s_k (w_k a(tau) + w_{k+1} b(tau)), a = tau - tau^2 / 2, b = tau^2 / 2
    (tau in [0, 1]): exact in (sigma_k, w_k, w_{k+1}) for a given s_k. Its extremum inside the
    interval, where the rate changes sign, lies at tau* = w_k / (w_k - w_{k+1}); an interval
    whose rate keeps its sign takes tau* = 1/2 (the bank is monotone there, between the node
    values). Returns tau* (N,), sigma(tau*) (N,) and the coefficients of sigma(tau*) in w_k and
    w_{k+1} (s_k a, s_k b) and in s_k (w_k a + w_{k+1} b), as (N, 2) and (N,).
    """
    w0, w1 = w[:-1], w[1:]
    turns = w0 * w1 < 0.0
    tau = np.full(w0.shape, 0.5)
    tau[turns] = w0[turns] / (w0[turns] - w1[turns])
    a, b = tau - 0.5 * tau * tau, 0.5 * tau * tau
    rate_part = w0 * a + w1 * b
    value = z_bank[:-1] + s * rate_part
    return tau, value, np.stack([s * a, s * b], axis=1), rate_part


def _rate_of(d: SubproblemData, control: int) -> Array:
    """The reference's rates of one control (K,)."""
    return d.w if d.w.ndim == 1 else d.w[:, control]


def bank_vertex_block(
    sub: FohSubproblem,
    state: int | None = None,
    control: int = 0,
    bounds: tuple[float, float] | None = None,
    name: str = "bank_between_nodes",
) -> Block:
    """sigma_min <= sigma <= sigma_max where the bank turns inside each interval
    (``bank_vertex``), so the flown bank, not only its node values, stays within the range:
    without these rows a bank rate that reverses within a long interval carried the bank to
    180 deg between nodes held at 80 deg (paper 002 case 1, 40 nodes). Rows k (upper) and
    N + k (lower) on sigma_k, w_k, w_{k+1} and, on the adaptive grid, s_k; at a converged
    reference tau* is the true turning point, so the bound holds along the whole interval.
    ``state``, ``control`` and ``bounds`` (low, high) put the same rows on another held state
    (an angle of attack and its rate)."""
    N = sub.N
    sigma = sub.state_index[4] if state is None else state
    low, high = (sub.bank_min, sub.bank_max) if bounds is None else bounds
    w_cols = sub.col_w if sub.controls == 1 else sub.col_w[:, control]
    cols = [sub.col_z[:-1, sigma], w_cols[:-1], w_cols[1:]]
    if sub.adaptive:
        cols.append(sub.col_s)
    col = np.stack(cols, axis=1)  # (N, 3 or 4)
    rows = np.arange(N)[:, None]
    Dz, Dw, Ds = sub.Dz[sigma], sub.Dw, sub.Ds

    def coefficients(d: SubproblemData) -> Array:
        """Scaled coefficients of sigma(tau*) on the interval's columns (N, 3 or 4)."""
        _, _, on_rates, on_length = bank_vertex(d.z[:, sigma], _rate_of(d, control), d.s)
        parts = [np.full((N, 1), Dz), on_rates * Dw]
        if sub.adaptive:
            parts.append(on_length[:, None] * Ds)
        return np.concatenate(parts, axis=1)

    def rhs(d: SubproblemData) -> Array:
        """sigma_max - sigma(tau*) for the upper rows, then sigma(tau*) - sigma_min."""
        value = bank_vertex(d.z[:, sigma], _rate_of(d, control), d.s)[1]
        return np.concatenate([high - value, value - low])

    return Block(
        name,
        "nonneg",
        2 * N,
        (
            Term(rows, col, update=coefficients),
            Term(N + rows, col, update=lambda d: -coefficients(d)),
        ),
        rhs=rhs,
    )


def inequality_blocks(sub: FohSubproblem) -> list[Block]:
    """Bank and bank-rate bounds, path, zone and between-node rows (each with its L1 buffer when
    weighted), the buffers' signs, the interval bounds and the soft and range terminal rows."""
    K, N, Dz, nb = sub.K, sub.N, sub.Dz, sub.block_cols.shape[1]
    r, th, ph, v, sigma = sub.state_index
    col_z, col_buf = sub.col_z, sub.col_buf
    blocks = [
        bound_block(
            "bank",
            col_z[:, sigma],
            Dz[sigma],
            sub.bank_max,
            lambda d: d.z[:, sigma],
            lower=sub.bank_min,
        ),
        bank_vertex_block(sub),
    ]
    if sub.bank_rate_max is not None:
        blocks.append(
            bound_block(
                "bank_rate", sub.col_bank_rate, sub.Dw, sub.bank_rate_max, lambda d: _rate_of(d, 0)
            )
        )
    alpha = sub.alpha
    if alpha is not None:  # an angle-of-attack state: its range at and between nodes, its rate
        a = alpha.index
        blocks.append(
            bound_block(
                "angle_of_attack",
                col_z[:, a],
                Dz[a],
                alpha.high,
                lambda d: d.z[:, a],
                lower=alpha.low,
            )
        )
        blocks.append(
            bank_vertex_block(sub, a, 1, (alpha.low, alpha.high), "angle_of_attack_between_nodes")
        )
        if alpha.rate_max is not None:
            blocks.append(
                bound_block(
                    "angle_of_attack_rate",
                    sub.col_w[:, 1],
                    sub.Dw,
                    alpha.rate_max,
                    lambda d: d.w[:, 1],
                )
            )
    buffered = 0  # the buffers cover the path, zone and between-node rows in that order

    def buffer(size: int) -> tuple[Term[SubproblemData], ...]:
        """The buffer term of the next ``size`` buffered rows (none when unweighted)."""
        nonlocal buffered
        if not sub.n_buffer:
            return ()
        cols = col_buf[buffered : buffered + size]
        buffered += size
        return (Term(np.arange(size), cols, -1.0),)

    if sub.n_limits:  # row m K + k: limit m at node k
        rows = np.arange(K)[:, None] + K * np.arange(sub.n_limits)[None, :]
        blocks.append(
            Block(
                "path",
                "nonneg",
                sub.n_limits * K,
                (
                    Term(rows, col_z[:, r, None], update=lambda d: d.path_gr * Dz[r]),
                    Term(rows, col_z[:, v, None], update=lambda d: d.path_gv * Dz[v]),
                    *_alpha_path_term(sub, rows),
                    *buffer(sub.n_limits * K),
                ),
                rhs=lambda d: -d.path_g.T.ravel(),
            )
        )
    if sub.n_zones:  # row z K + k: zone z at node k
        rows = K * np.arange(sub.n_zones)[:, None] + np.arange(K)[None, :]
        blocks.append(
            Block(
                "zone",
                "nonneg",
                sub.n_zones * K,
                (
                    Term(rows, col_z[None, :, ph], update=lambda d: -d.zone_clat * Dz[ph]),
                    Term(rows, col_z[None, :, th], update=lambda d: -d.zone_clon * Dz[th]),
                    *buffer(sub.n_zones * K),
                ),
                rhs=lambda d: d.zone_c.ravel(),
            )
        )
    if sub.n_inner:  # row m N + k: constraint m over interval k, on the interval's variables
        rows = np.arange(N)[:, None] + N * np.arange(sub.n_inner)[None, :]
        scale = sub.block_scale
        blocks.append(
            Block(
                "between_nodes",
                "nonneg",
                sub.n_inner * N,
                (
                    Term(
                        rows[:, :, None],
                        sub.block_cols[:, None, :],
                        update=lambda d: _inner(d)[:, :, :nb] * scale,
                    ),
                    *buffer(sub.n_inner * N),
                ),
                rhs=lambda d: -_inner_g(d).T.ravel(),
            )
        )
    if sub.n_buffer:
        rows = np.arange(sub.n_buffer)
        blocks.append(Block("buffers", "nonneg", sub.n_buffer, (Term(rows, col_buf, -1.0),)))
    if sub.grid is not None:
        g = sub.grid
        rows = np.arange(N)
        blocks.append(
            Block(
                "interval",
                "nonneg",
                2 * N,
                (Term(rows, sub.col_s, sub.Ds), Term(N + rows, sub.col_s, -sub.Ds)),
                rhs=lambda d: np.concatenate(
                    [
                        np.minimum(g.delta_max - d.s, g.delta_trust),
                        np.minimum(d.s - g.delta_min, g.delta_trust),
                    ]
                ),
            )
        )
    if sub.grid is not None and sub.grid.final_time is None and sub.grid.final_time_max is not None:
        latest = sub.grid.final_time_max
        blocks.append(
            Block(
                "final_time_max",
                "nonneg",
                1,
                (Term(np.zeros(N, dtype=np.int64), sub.col_s, sub.Ds),),
                rhs=lambda d: np.array([latest - float(np.sum(d.s))]),
            )
        )
    last = col_z[-1]
    ranges = [t for t in sub.terminal if t.kind == "range"]
    blocks.append(soft_block(sub.soft, last, sub.col_soft, Dz, _last_node))
    blocks.append(range_block(ranges, last, Dz, _last_node))
    return blocks


def _alpha_path_term(sub: FohSubproblem, rows: Array) -> tuple[Term[SubproblemData], ...]:
    """The path rows' term in an angle-of-attack state (none when alpha is scheduled)."""
    if sub.alpha is None:
        return ()
    a = sub.alpha.index
    scale = sub.Dz[a]

    def values(d: SubproblemData) -> Array:
        assert d.path_ga is not None
        return d.path_ga * scale

    return (Term(rows, sub.col_z[:, a, None], update=values),)


def _last_node(d: SubproblemData) -> Array:
    """The reference's last node."""
    return d.z[-1]


def row_blocks(sub: FohSubproblem) -> list[Block]:
    """Every row block of the subproblem, in row order."""
    return equality_blocks(sub) + inequality_blocks(sub)
