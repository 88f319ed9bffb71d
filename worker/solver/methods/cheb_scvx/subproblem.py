"""The convex subproblem of the Chebyshev SCvx (paper 001 problem P2, eqs. 35-42) in Clarabel's
form: every variable is a scaled change from the reference (state, lift vector, segment
durations), the collocation rows are relaxed by an L1 virtual control, the path rows (added at
the points of the violated set), zone rows, waypoint cones and terminal rows by L1 slacks, all
penalized with one weight; the lift vector lies in the relaxed cone u1^2 + u2^2 <= u3 (eq. 34)
between the bank cuts (eq. 41) and the lift bounds (eq. 40), in the trust box (eq. 42).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike

from worker.solver.conic import ConeProblem, ConeSpec
from worker.solver.methods.cheb_scvx.linearization import (
    RHO_FLOOR,
    ChebIterate,
    ChebLinearization,
)
from worker.solver.methods.cheb_scvx.segments import Segments
from worker.solver.models.point_mass import PH, TH, R, V
from worker.solver.problem import EntryProblem

Array = np.ndarray
PATH_UNIT = 0.01
"""Unit of a path row's slack: 1 % of the limit (ln p / p_max)."""
ZONE_UNIT = math.radians(0.5)
"""Unit of a zone or waypoint slack: 0.5 deg of arc."""
STEP_REGULARIZATION = 1.0e-4
"""Weight of 0.5 |step|^2 (scaled units) in the subproblem per unit of the objective's largest
coefficient (``regularization_scale``): the box-bounded, L1-penalized program is otherwise so
degenerate (a face of optimal vertices) that the interior-point solver stalls short of its
tolerance; this makes the optimum unique at a cost far below the objective's resolution, and the
ratio test reads only the linear model. Measured against the objective, not fixed: a fixed weight
that suits minimum time (10 per 10 s) damped a final-latitude objective (0.5 per 0.5 deg) into a
creep that stopped 1.1 % short on the heat-limited Shuttle."""
BOUND_UNIT = 1.0e-3
"""Unit of the objective bound's slack in the tie-breaking phase, per unit of the objective's
largest coefficient per scaled unit (``regularization_scale``): 1e-3 of a scaled unit."""
GAP_UNIT = 0.01
"""Unit of the lift manifold's slack: 1 % of the lift share squared (u3 - u1^2 - u2^2)."""
ZONE_WINDOW = math.radians(2.0)
"""A zone's rows are added where the reference is closer than the trust box's reach plus this."""


@dataclass(frozen=True)
class Units:
    """Units of the scaled changes: states (6,), lift vector (3,), segment durations."""

    y: Array
    u: Array
    t: float


@dataclass(frozen=True)
class TerminalBound:
    """lo <= y_last[state] <= hi, relaxed by a penalized slack."""

    state: int
    lo: float
    hi: float


@dataclass(frozen=True)
class Waypoint:
    """A waypoint at a segment joint: centre, radius (rad) and the longitude factor of its
    metric (cos latitude on the sphere, 1 on the flat map)."""

    point: int
    latitude: float
    longitude: float
    radius: float
    lon_factor: float


@dataclass
class Setup:
    """What stays fixed over the run: units, bounds, terminal rows, waypoints, objective."""

    units: Units
    lam2: tuple[float, float]
    tan_bank: tuple[float, float]  # tan of the lower and upper bank bound
    terminal: list[TerminalBound]
    waypoints: list[Waypoint]
    objective_time: float  # weight per nondimensional flight time
    objective_state: dict[int, float]  # weight per nondimensional last-point state
    objective_heat: float  # weight per (W/m^2 x nondimensional time)
    weight: float  # L1 penalty of the virtual control and the slacks
    final_time: tuple[float | None, float | None] = (None, None)  # min/max total, fixed: equal
    lift_weight: float = 0.0  # per unit of the integral of u3 over tau (a polar's)
    unused_lift_weight: float = 0.0  # per point and unit of 1 - |(u1, u2)| (u3 fixed)
    bank_rate_max: float | None = None  # rad per nondimensional time
    on_manifold: bool = False  # the lift vector on u3 = u1^2 + u2^2 (linearized), not the cone
    smooth_weight: float = 0.0  # tie-breaking: per unit of sum |u_k+1 - u_k|^2 (x scale)
    objective_room: float | None = None  # tie-breaking: the bound less the reference's value

    @property
    def fixed_lift(self) -> bool:
        """u3 is fixed (a scheduled vehicle's lam range is [1, 1])."""
        return self.lam2[0] == self.lam2[1]


@dataclass
class Columns:
    """Column offsets of the variable groups."""

    y: int
    u: int
    t: int
    nu: int  # 2 per collocation row (plus, minus): 12 per state point after the first
    slack: int
    n: int
    path_points: Array = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    path_limits: Array = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    slack_names: list[str] = field(default_factory=list)
    scale: float = 1.0
    """The objective's largest coefficient per scaled unit (``regularization_scale``)."""
    terminal_rows: int = 0
    """The first of the terminal bounds' rows (two per bound, upper then lower) in the
    nonnegative block: their multipliers weigh the merit (``method.merit_weight_of``)."""


class _Rows:
    """Triplets of one cone block: rows added in order, b alongside."""

    def __init__(self) -> None:
        self.rows: list[Array] = []
        self.cols: list[Array] = []
        self.vals: list[Array] = []
        self.b: list[Array] = []
        self.m = 0

    def add(self, b: ArrayLike, *terms: tuple[ArrayLike, ArrayLike, ArrayLike]) -> None:
        """Rows with right-hand side ``b``; each term (local row, column, value) broadcast."""
        b = np.atleast_1d(np.asarray(b, dtype=float))
        for local, col, val in terms:
            loc, c, v = np.broadcast_arrays(
                np.asarray(local, dtype=np.int64), np.asarray(col, dtype=np.int64), val
            )
            self.rows.append(loc.ravel() + self.m)
            self.cols.append(c.ravel())
            self.vals.append(np.asarray(v, dtype=float).ravel())
        self.b.append(b)
        self.m += b.size


def _stack(blocks: list[_Rows], n: int) -> tuple[sp.csc_matrix, Array]:
    rows, cols, vals, bs, offset = [], [], [], [], 0
    for blk in blocks:
        rows += [r + offset for r in blk.rows]
        cols += blk.cols
        vals += blk.vals
        bs += blk.b
        offset += blk.m
    A = sp.csc_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(offset, n)
    )
    return A, np.concatenate(bs)


def build(
    problem: EntryProblem,
    segments: Segments,
    setup: Setup,
    ref: ChebIterate,
    lin: ChebLinearization,
    path_set: Array,
    trust: Array,
    rate_set: Array | None = None,
) -> tuple[ConeProblem, Columns]:
    """The subproblem about ``ref``; ``path_set`` (Q, m) marks the path rows to add,
    ``rate_set`` (``Segments.rate_rows``,) the places whose bank rate is bounded, and ``trust``
    (6 + 3 + 1,) holds the trust box's half-widths in scaled units."""
    un = setup.units
    P, Q, S = segments.state_points, segments.control_points, segments.count
    # a zone's rows where the reference is within the trust box's reach of it (the rest
    # cannot be entered by this step)
    reach = float(max(trust[PH] * un.y[PH], trust[TH] * un.y[TH])) + ZONE_WINDOW
    zone_rows_at = [np.flatnonzero(z.c - zone.radius < reach)
                    for z, zone in zip(lin.zones, problem.no_fly_zones, strict=True)]  # fmt: skip
    zone_rows = sum(near.size for near in zone_rows_at)
    pts, lims = np.nonzero(path_set)
    rate_pts = (
        np.flatnonzero(rate_set)
        if rate_set is not None and setup.bank_rate_max is not None
        else np.zeros(0, dtype=np.int64)
    )
    n_slack = pts.size + 2 * rate_pts.size + zone_rows + len(setup.waypoints) + len(setup.terminal)
    if setup.on_manifold:
        n_slack += Q
    if setup.objective_room is not None:
        n_slack += 1
    cy, cu, ct = 0, 6 * P, 6 * P + 3 * Q
    cnu = ct + S
    cs = cnu + 12 * (P - 1)
    cols = Columns(cy, cu, ct, cnu, cs, cs + n_slack, pts, lims)
    n = cols.n
    yc = cy + 6 * np.arange(P)[:, None] + np.arange(6)[None, :]  # (P, 6)
    uc = cu + 3 * np.arange(Q)[:, None] + np.arange(3)[None, :]  # (Q, 3)
    q = np.zeros(n)

    zero, nonneg, socs = _Rows(), _Rows(), _Rows()
    soc_dims: list[int] = []
    # collocation in integral form (eq. 36, see linearization.defects): for i = 1..n,
    # dy_i - dy_0 - (T/2) sum_k B_ik (A_k dy_k + B_k du_k) - (B f)_i / 2 dT - nu = -defect,
    # each row divided by its state's unit
    row = 0
    for s in range(S):
        Bm = segments.integration(s)[1:]  # (n, n + 1)
        ctrl = np.arange(Q)[segments.controls_of(s)]
        states = np.arange(P)[segments.states_of(s)]
        n_s = states.size - 1
        half_t = 0.5 * ref.T[s]
        Bf = Bm @ lin.f[ctrl]  # (n, 6)
        local = np.arange(n_s)
        for j in range(6):
            scale = 1.0 / un.y[j]
            # only the partials this rate has (A is about a third zeros, B five sixths): the
            # rows are dense in the interval's points, so structural zeros would triple them
            a_on = np.flatnonzero(np.any(lin.A[ctrl, j, :] != 0.0, axis=0))
            b_on = np.flatnonzero(np.any(lin.B[ctrl, j, :] != 0.0, axis=0))
            a_rows = lin.A[ctrl, j, :][:, a_on]
            b_rows = lin.B[ctrl, j, :][:, b_on]
            a_vals = -half_t * Bm[:, :, None] * a_rows[None, :, :] * un.y[a_on] * scale
            b_vals = -half_t * Bm[:, :, None] * b_rows[None, :, :] * un.u[b_on] * scale
            nu_plus = cnu + 12 * (row + local) + 2 * j
            zero.add(
                -lin.defects[row : row + n_s, j] * scale,
                (local, yc[states[1:], j], 1.0),
                (local, yc[states[0], j], -1.0),
                (local[:, None, None], yc[states][:, a_on][None, :, :], a_vals),
                (local[:, None, None], uc[ctrl][:, b_on][None, :, :], b_vals),
                (local, ct + s, -0.5 * Bf[:, j] * un.t * scale),
                (local, nu_plus, -1.0),
                (local, nu_plus + 1, 1.0),
            )
        row += n_s
    # the initial state is given
    zero.add((problem.y0 - ref.y[0]) / un.y, (np.arange(6), yc[0], un.y / un.y))
    # the intervals of a leg share its duration equally
    for leg in range(segments.leg_count):
        within = segments.leg_intervals(leg)
        if within.size > 1:
            rest = within[1:]
            k = np.arange(rest.size)
            zero.add(
                -(ref.T[rest] - ref.T[within[0]]) / un.t,
                (k, ct + rest, 1.0),
                (k, ct + within[0], -1.0),
            )
    # fixed total flight time
    t_lo, t_hi = setup.final_time
    total = float(np.sum(ref.T))
    if t_lo is not None and t_lo == t_hi:
        zero.add(np.array([(t_lo - total) / un.t]), (np.zeros(S), ct + np.arange(S), 1.0))
        t_lo = t_hi = None
    # nonnegative rows: b - A x >= 0
    n_nu = 12 * (P - 1)
    q[cnu : cnu + n_nu] = setup.weight
    nonneg.add(np.zeros(n_nu), (np.arange(n_nu), cnu + np.arange(n_nu), -1.0))
    q[cs : cs + n_slack] = setup.weight
    nonneg.add(np.zeros(n_slack), (np.arange(n_slack), cs + np.arange(n_slack), -1.0))
    # trust box (eq. 42)
    for group, width in ((yc, trust[:6]), (uc, trust[6:9])):
        w = np.broadcast_to(width, group.shape).ravel()
        idx = np.arange(group.size)
        nonneg.add(
            np.concatenate([w, w]),
            (idx, group.ravel(), 1.0),
            (idx + group.size, group.ravel(), -1.0),
        )
    idx = np.arange(S)
    nonneg.add(np.full(2 * S, trust[9]), (idx, ct + idx, 1.0), (idx + S, ct + idx, -1.0))
    # durations stay positive; total flight-time bounds
    nonneg.add(ref.T / un.t - 1e-3, (idx, ct + idx, -1.0))
    if t_hi is not None:
        nonneg.add(np.array([(t_hi - total) / un.t]), (np.zeros(S), ct + idx, 1.0))
    if t_lo is not None:
        nonneg.add(np.array([(total - t_lo) / un.t]), (np.zeros(S), ct + idx, -1.0))
    # lift bounds lam_min^2 <= u3 <= lam_max^2 (eq. 40) and the bank cuts (eq. 41)
    lo2, hi2 = setup.lam2
    u3 = ref.u[:, 2]
    iq = np.arange(Q)
    if setup.fixed_lift:  # a scheduled vehicle's: an equality, not a closed interval
        zero.add((hi2 - u3) / un.u[2], (iq, uc[:, 2], 1.0))
    else:
        nonneg.add(
            np.concatenate([hi2 - u3, u3 - lo2]),
            (iq, uc[:, 2], un.u[2]),
            (iq + Q, uc[:, 2], -un.u[2]),
        )
    tan_lo, tan_hi = setup.tan_bank
    u1, u2 = ref.u[:, 0], ref.u[:, 1]
    nonneg.add(
        np.concatenate([tan_hi * u1 - u2, u2 - tan_lo * u1]),
        (iq, uc[:, 0], -tan_hi * un.u[0]),
        (iq, uc[:, 1], un.u[1]),
        (iq + Q, uc[:, 0], tan_lo * un.u[0]),
        (iq + Q, uc[:, 1], -un.u[1]),
    )
    slack = cs
    # path rows at the violated set (eq. 38): (g + grad . d) / unit <= slack
    if pts.size:
        sp_ = segments.state_of_control[pts]
        pl = lin.path
        k = np.arange(pts.size)
        nonneg.add(
            -pl.g[pts, lims] / PATH_UNIT,
            (k, yc[sp_, R], pl.g_r[pts, lims] * un.y[R] / PATH_UNIT),
            (k, yc[sp_, V], pl.g_v[pts, lims] * un.y[V] / PATH_UNIT),
            (k, uc[pts, 2], pl.g_u3[pts, lims] * un.u[2] / PATH_UNIT),
            (k, slack + k, -1.0),
        )
        slack += pts.size
    # bank-rate rows where the reference nears the limit: +-w / (r T / 2) - 1 - dT / T <= slack
    if rate_pts.size:
        assert setup.bank_rate_max is not None
        slack = _bank_rate_rows(nonneg, segments, ref, rate_pts, setup.bank_rate_max, uc, ct,
                                un, slack)  # fmt: skip
    # zones at the points and between them: (R - c - grad . d) / unit <= slack
    if lin.zones:
        weights = segments.between_rows
        for zone, zl, near in zip(problem.no_fly_zones, lin.zones, zone_rows_at, strict=True):
            m = near.size
            k = np.arange(m)
            lat_cols, lat_vals = _point_terms(
                yc[:, PH], weights, zl.c_lat * un.y[PH] / ZONE_UNIT, P
            )
            lon_cols, lon_vals = _point_terms(
                yc[:, TH], weights, zl.c_lon * un.y[TH] / ZONE_UNIT, P
            )
            nonneg.add(
                (zl.c[near] - zone.radius) / ZONE_UNIT,
                (k[:, None], lat_cols[near], -lat_vals[near]),
                (k[:, None], lon_cols[near], -lon_vals[near]),
                (k, slack + k, -1.0),
            )
            slack += m
    # waypoints at the joints: |(dlat, f dlon)| <= radius + slack (second-order cones)
    for wp in setup.waypoints:
        p = wp.point
        dlat, dlon = ref.y[p, PH] - wp.latitude, ref.y[p, TH] - wp.longitude
        socs.add(
            np.array([wp.radius, dlat, wp.lon_factor * dlon]),
            (0, slack, -ZONE_UNIT),
            (1, yc[p, PH], -un.y[PH]),
            (2, yc[p, TH], -wp.lon_factor * un.y[TH]),
        )
        soc_dims.append(3)
        slack += 1
    # on the lift manifold: |gap + grad . d| / unit <= s, the gap u3 - u1^2 - u2^2 linearized
    # (before the terminal slacks, whose rows the merit weight reads last)
    if setup.on_manifold:
        gap = ref.u[:, 2] - ref.u[:, 0] ** 2 - ref.u[:, 1] ** 2
        g1 = -2.0 * ref.u[:, 0] * un.u[0] / GAP_UNIT
        g2 = -2.0 * ref.u[:, 1] * un.u[1] / GAP_UNIT
        g3 = np.full(Q, un.u[2] / GAP_UNIT)
        both = np.concatenate([iq, iq + Q])
        nonneg.add(
            np.concatenate([-gap, gap]) / GAP_UNIT,
            (both, np.tile(uc[:, 0], 2), np.concatenate([g1, -g1])),
            (both, np.tile(uc[:, 1], 2), np.concatenate([g2, -g2])),
            (both, np.tile(uc[:, 2], 2), np.concatenate([g3, -g3])),
            (both, slack + np.tile(iq, 2), -1.0),
        )
        slack += Q
    bound_slack = slack  # the objective's bound: its row once the objective is built
    if setup.objective_room is not None:
        slack += 1
    # terminal bounds on the last point, relaxed: (y - hi)/unit <= s, (lo - y)/unit <= s
    cols.terminal_rows = nonneg.m
    last = P - 1
    for t in setup.terminal:
        j = t.state
        yj = ref.y[last, j]
        nonneg.add(
            np.array([(t.hi - yj) / un.y[j], (yj - t.lo) / un.y[j]]),
            (np.array([0, 1]), yc[last, j], np.array([1.0, -1.0])),
            (np.array([0, 1]), slack, -1.0),
        )
        slack += 1
    # the relaxed lift cone (eq. 34): |(2 u1, 2 u2, u3 - 1)| <= u3 + 1
    for qi in range(0 if setup.on_manifold else Q):
        socs.add(
            np.array([u3[qi] + 1.0, 2.0 * u1[qi], 2.0 * u2[qi], u3[qi] - 1.0]),
            (np.array([0, 3]), uc[qi, 2], -un.u[2]),
            (1, uc[qi, 0], -2.0 * un.u[0]),
            (2, uc[qi, 1], -2.0 * un.u[1]),
        )
        soc_dims.append(4)
    # the induced-drag share u3 weighed lightly: where the objective is indifferent to it (a
    # push-over at no lift) the relaxed cone is made tight instead of left slack
    if setup.lift_weight and not setup.fixed_lift:
        for s in range(S):
            ctrl = np.arange(Q)[segments.controls_of(s)]
            q[uc[ctrl, 2]] += setup.lift_weight * segments.quadrature(s) * un.u[2]
    # with u3 fixed (a scheduled vehicle) the lift share left unused, 1 - |(u1, u2)|, at each
    # point, linearized along the reference's direction (a concave term's tangent: the model
    # bounds it from above); at a reference with no lift, along u1
    if setup.unused_lift_weight and setup.fixed_lift:
        norm = np.hypot(u1, u2)
        safe = np.maximum(norm, 1e-300)
        along = np.where(norm > 0.0, u1 / safe, 1.0)
        across = np.where(norm > 0.0, u2 / safe, 0.0)
        q[uc[:, 0]] -= setup.unused_lift_weight * along * un.u[0]
        q[uc[:, 1]] -= setup.unused_lift_weight * across * un.u[1]
    # objective: time, last-point states, heat load (Clenshaw-Curtis quadrature)
    objective = np.zeros(n)
    objective[ct : ct + S] += setup.objective_time * un.t
    for j, wgt in setup.objective_state.items():
        objective[yc[last, j]] += wgt * un.y[j]
    if setup.objective_heat:
        for s in range(S):
            ctrl = np.arange(Q)[segments.controls_of(s)]
            w = segments.quadrature(s) * 0.5 * setup.objective_heat
            states = segments.state_of_control[ctrl]
            np.add.at(objective, yc[states, R], w * ref.T[s] * lin.heat_r[ctrl] * un.y[R])
            np.add.at(objective, yc[states, V], w * ref.T[s] * lin.heat_v[ctrl] * un.y[V])
            objective[uc[ctrl, 2]] += w * ref.T[s] * lin.heat_u3[ctrl] * un.u[2]
            objective[ct + s] += float(w @ lin.heat[ctrl]) * un.t
    q += objective
    scale = regularization_scale(objective)
    cols.scale = scale
    if setup.objective_room is not None:
        # the objective no worse than its bound: (room - objective . x) / unit + s >= 0
        on = np.flatnonzero(objective)
        unit = BOUND_UNIT * scale
        nonneg.add(
            np.array([setup.objective_room / unit]),
            (np.zeros(on.size), on, objective[on] / unit),
            (0, bound_slack, -1.0),
        )
    A, b = _stack([zero, nonneg, socs], n)
    cones = ConeSpec(zero.m, nonneg.m, tuple(soc_dims))
    diagonal = np.zeros(n)
    diagonal[:cnu] = STEP_REGULARIZATION * scale
    P = sp.diags(diagonal, format="csc")
    if setup.smooth_weight:
        # w |du_r + un D d|^2 per component: 2 w un^2 D'D in P, 2 w un D' du_r in q
        smooth = setup.smooth_weight * scale
        D = sp.diags([-np.ones(Q - 1), np.ones(Q - 1)], [0, 1], shape=(Q - 1, Q), format="csc")
        for c in range(3):
            sel = sp.csc_matrix((np.ones(Q), (np.arange(Q), uc[:, c])), shape=(Q, n))
            B = un.u[c] * (D @ sel)
            P = P + 2.0 * smooth * (B.T @ B)
            q += 2.0 * smooth * (B.T @ np.diff(ref.u[:, c]))
        P = sp.triu(P, format="csc")
    return ConeProblem(P, q, A, b, cones), cols


def smoothing(setup: Setup, u: Array, scale: float) -> float:
    """The tie-breaking phase's smoothing term on lift vectors ``u`` (Q, 3), 0 before it."""
    if not setup.smooth_weight:
        return 0.0
    return setup.smooth_weight * scale * float(np.sum(np.diff(u, axis=0) ** 2))


def regularization_scale(objective: Array) -> float:
    """The largest objective coefficient per scaled unit (1 without an objective term: a pure
    feasibility problem)."""
    largest = float(np.max(np.abs(objective), initial=0.0))
    return largest if largest > 0.0 else 1.0


def _bank_rate_rows(
    nonneg: _Rows,
    segments: Segments,
    ref: ChebIterate,
    places: Array,
    rate_max: float,
    uc: Array,
    ct: int,
    un: Units,
    slack: int,
) -> int:
    """|d sigma/dt| <= rate_max at ``places`` (indices into ``Segments.rate_evaluation``'s
    rows: points and between samples), linearized in the interval's lift vector and duration:
    with a = E u1, b = E u2, a' = F u1, b' = F u2 (E, F the places' value and tau-derivative
    rows), rho = a^2 + b^2 and w = (a b' - b a') / rho the rate is 2 w / T, and
    dw/du1 = (b' E - b F) / rho - 2 w a E / rho, dw/du2 = (a F - a' E) / rho - 2 w b E / rho.
    Two rows per place (either sign), one slack each in units of 1 % of the limit."""
    sizes = [e.shape[0] for e, _ in segments.rate_evaluation]
    first = np.concatenate([[0], np.cumsum(sizes)])
    seg_of = np.repeat(np.arange(segments.count), sizes)
    row = 0
    for s in np.unique(seg_of[places]).tolist():
        ctrl = np.arange(uc.shape[0])[segments.controls_of(s)]
        local = places[seg_of[places] == s] - first[s]
        e_all, f_all = segments.rate_evaluation[s]
        e, f = e_all[local], f_all[local]
        u1, u2 = ref.u[ctrl, 0], ref.u[ctrl, 1]
        a, b, da, db = e @ u1, e @ u2, f @ u1, f @ u2
        rho = np.maximum(a * a + b * b, RHO_FLOOR)
        w = (a * db - b * da) / rho
        w_1 = (db[:, None] * e - b[:, None] * f - (2.0 * w * a)[:, None] * e) / rho[:, None]
        w_2 = (a[:, None] * f - da[:, None] * e - (2.0 * w * b)[:, None] * e) / rho[:, None]
        half = 0.5 * rate_max * ref.T[s]
        m = local.size
        k = np.arange(m)
        for sign in (1.0, -1.0):
            nonneg.add(
                -(sign * w / half - 1.0) / PATH_UNIT,
                (k[:, None], uc[ctrl, 0][None, :], sign * w_1 * un.u[0] / half / PATH_UNIT),
                (k[:, None], uc[ctrl, 1][None, :], sign * w_2 * un.u[1] / half / PATH_UNIT),
                (k, ct + s, -un.t / ref.T[s] / PATH_UNIT),
                (k, slack + row + k, -1.0),
            )
            row += m
    return slack + row


def _point_terms(
    col_of_point: Array, weights: list[tuple[Array, Array]], grad: Array, points: int
) -> tuple[Array, Array]:
    """Columns and values of a gradient over the state points followed by the samples, each
    sample spread over its segment's points by its interpolation weights; padded to a
    rectangle with zero values."""
    width = max([1] + [w.size for _, w in weights])
    m = points + len(weights)
    cols = np.zeros((m, width), dtype=np.int64)
    vals = np.zeros((m, width))
    cols[:points, 0] = col_of_point
    vals[:points, 0] = grad[:points]
    for i, (states, w) in enumerate(weights):
        cols[points + i, : w.size] = col_of_point[states]
        vals[points + i, : w.size] = grad[points + i] * w
    return cols, vals


def step_of(
    x: Array, cols: Columns, units: Units, segments: Segments
) -> tuple[Array, Array, Array]:
    """(dy (P, 6), du (Q, 3), dT (S,)) nondimensional from a solution."""
    P, Q, S = segments.state_points, segments.control_points, segments.count
    dy = x[cols.y : cols.y + 6 * P].reshape(P, 6) * units.y[None, :]
    du = x[cols.u : cols.u + 3 * Q].reshape(Q, 3) * units.u[None, :]
    dT = x[cols.t : cols.t + S] * units.t
    return dy, du, dT
