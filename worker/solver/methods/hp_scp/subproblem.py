"""Paper 003's convex subproblem about a reference: the linearized CGL collocation rows with an
L1 virtual control, the state, control and rate bounds, the linearized path limits and no-fly
zones with L1 slacks, the terminal conditions with an L1 buffer, the objective's linear terms and
a quadratic trust-region penalty on every scaled change (paper 003 eqs. 52-60 in the soft trust
region form; the penalty weight is the globalization's).

Variables, all scaled: point changes dz / u_z (K, 8), rate changes dw / u_w (K, 2), the final
time's change dt_f / u_t, with a control-effort objective the rates' magnitudes e >= |w| / u_w
(K, 2), then the nonnegative virtual controls nu+ and nu- (K-1, 8), path slacks (L, K), zone
slacks (Z, K) and terminal buffers (one per fixed condition).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from worker.solver.conic import ConeProblem, ConeSpec
from worker.solver.methods.hp_scp.linearization import PHI, THETA, HpIterate, Linearization
from worker.solver.models.alpha_bank_state import ALPHA, SIGMA
from worker.solver.problem import EntryProblem
from worker.solver.transcription.terminal import TerminalRow

Array = np.ndarray
NZ, NW = 8, 2
R, V = 0, 3


@dataclass(frozen=True)
class Units:
    """Units of the scaled changes: states (8,), rates (2,), final time (nondimensional)."""

    z: Array
    w: Array
    t: float


@dataclass(frozen=True)
class Columns:
    """First column of each variable block and the total count (and, once built, the first
    row of the slacked inequality blocks)."""

    K: int
    L: int
    Z: int
    T: int
    E: int = 0
    """Effort columns: 2 K with a control-effort objective, else none."""
    rows: dict[str, int] = field(default_factory=dict, compare=False)

    @property
    def w(self) -> int:
        return self.K * NZ

    @property
    def t(self) -> int:
        return self.K * (NZ + NW)

    @property
    def effort(self) -> int:
        return self.t + 1

    @property
    def nu_plus(self) -> int:
        return self.effort + self.E

    @property
    def nu_minus(self) -> int:
        return self.nu_plus + (self.K - 1) * NZ

    @property
    def path(self) -> int:
        return self.nu_minus + (self.K - 1) * NZ

    @property
    def zone(self) -> int:
        return self.path + self.L * self.K

    @property
    def terminal(self) -> int:
        return self.zone + self.Z * self.K

    @property
    def collocation_rows(self) -> int:
        """The collocation rows, first among the equality rows."""
        return (self.K - 1) * NZ

    @property
    def steps(self) -> int:
        """Number of step columns (states, rates, final time): the trust-penalized ones."""
        return self.t + 1

    @property
    def n(self) -> int:
        return self.terminal + self.T

    def z(self, k: Array | int, a: Array | int) -> Array:
        return np.asarray(k) * NZ + np.asarray(a)

    def wcol(self, k: Array | int, c: Array | int) -> Array:
        return self.w + np.asarray(k) * NW + np.asarray(c)


@dataclass
class ObjectiveWeights:
    """Linear cost of the step columns: on the final time and on the last point's states (per
    unit of the scaled change), plus the constant part on the reference."""

    tf: float
    final: Array  # (8,) per unit of the nondimensional final state
    effort: float = 0.0
    """Weight of the control effort t_f sum_k W_k (|alpha'_k| + |sigma'_k|) (rad, the rates
    per nondimensional time, W the mesh's quadrature weights on [0, 1])."""


class _Rows:
    """COO triplets and right-hand sides of one cone block."""

    def __init__(self) -> None:
        self.r: list[Array] = []
        self.c: list[Array] = []
        self.v: list[Array] = []
        self.b: list[Array] = []
        self.count = 0

    def add(self, rows: Array, cols: Array, vals: Array, rhs: Array) -> None:
        """Entries at local rows ``rows`` (0-based in this call's block of ``len(rhs)`` rows)."""
        self.r.append(np.asarray(rows, dtype=np.int64).ravel() + self.count)
        self.c.append(np.asarray(cols, dtype=np.int64).ravel())
        self.v.append(np.asarray(vals, dtype=float).ravel())
        rhs = np.atleast_1d(np.asarray(rhs, dtype=float))
        self.b.append(rhs)
        self.count += rhs.size


def build(
    problem: EntryProblem,
    ref: HpIterate,
    lin: Linearization,
    units: Units,
    terminal: list[TerminalRow],
    objective: ObjectiveWeights,
    *,
    weight_virtual: float,
    weight_trust: float,
    tf_min: float,
    box: Array | None = None,
    box_rates: float = 0.0,
    box_tf: float = 0.0,
    hold_time: bool = False,
    rate_weight: float = 0.0,
    curvature: Array | None = None,
    between_points: bool = True,
) -> tuple[ConeProblem, Columns]:
    """The subproblem about ``ref`` (see the module docstring)."""
    pat = ref.pattern
    K = pat.num_points
    soft = [t for t in terminal if t.kind == "soft"]
    effort = objective.effort > 0.0
    cols = Columns(K, lin.path.g.shape[0], lin.zone_c.shape[0], len(soft), 2 * K if effort else 0)
    uz, uw, ut = units.z, units.w, units.t
    eq, ineq = _Rows(), _Rows()
    A, B, S = lin.dyn.A, lin.dyn.B, lin.dyn.S
    assert A is not None and B is not None
    M = K - 1
    # collocation rows (m, a): dz_i - dz_p - sum_j c_ij (A_j dz_j + B_j dw_j + S_j dtf) + nu = -d
    m_of_pair = pat.pair_row - 1
    a_idx = np.arange(NZ)
    rows_a = m_of_pair[:, None, None] * NZ + a_idx[None, :, None] + 0 * a_idx[None, None, :]
    cols_a = cols.z(pat.pair_col[:, None, None], a_idx[None, None, :]) + 0 * a_idx[None, :, None]
    vals_a = -pat.coef[:, None, None] * A[pat.pair_col] * (uz[None, None, :] / uz[None, :, None])
    c_idx = np.arange(NW)
    rows_b = m_of_pair[:, None, None] * NZ + a_idx[None, :, None] + 0 * c_idx[None, None, :]
    cols_b = cols.wcol(pat.pair_col[:, None, None], c_idx[None, None, :]) + 0 * a_idx[None, :, None]
    vals_b = -pat.coef[:, None, None] * B[pat.pair_col] * (uw[None, None, :] / uz[None, :, None])
    s_sum = np.zeros((K, NZ))
    np.add.at(s_sum, pat.pair_row, pat.coef[:, None] * S[pat.pair_col])
    m_all = np.arange(M)
    rows_id = (m_all[:, None] * NZ + a_idx[None, :]).ravel()
    eq.add(
        np.concatenate(
            [
                rows_a.ravel(),
                rows_b.ravel(),
                rows_id,
                rows_id,
                rows_id,
                rows_id,
                rows_id,
            ]
        ),
        np.concatenate(
            [
                cols_a.ravel(),
                cols_b.ravel(),
                cols.z(m_all[:, None] + 1, a_idx[None, :]).ravel(),
                cols.z(pat.start[:, None], a_idx[None, :]).ravel(),
                np.full(M * NZ, cols.t),
                cols.nu_plus + rows_id,
                cols.nu_minus + rows_id,
            ]
        ),
        np.concatenate(
            [
                vals_a.ravel(),
                vals_b.ravel(),
                np.ones(M * NZ),
                -np.ones(M * NZ),
                (-s_sum[1:] * (ut / uz[None, :])).ravel(),
                np.ones(M * NZ),
                -np.ones(M * NZ),
            ]
        ),
        (-lin.defects / uz[None, :]).ravel(),
    )
    # the initial point: the point-mass states fixed, bank and alpha when given
    fixed0 = list(range(6))
    values0 = list(problem.y0)
    if problem.initial_bank is not None:
        fixed0.append(SIGMA)
        values0.append(problem.initial_bank)
    if problem.initial_alpha is not None:
        fixed0.append(ALPHA)
        values0.append(problem.initial_alpha)
    f0 = np.asarray(fixed0)
    eq.add(
        np.arange(f0.size),
        cols.z(0, f0),
        np.ones(f0.size),
        (np.asarray(values0) - ref.z[0, f0]) / uz[f0],
    )
    # bounds on bank and alpha at every point, then on their rates
    k_all = np.arange(K)
    bounds = [(SIGMA, problem.bank_min, problem.bank_max)]
    if problem.alpha_range is not None:
        bounds.append((ALPHA, *problem.alpha_range))
    for a, lo, hi in bounds:
        ineq.add(
            np.concatenate([k_all, K + k_all]),
            np.concatenate([cols.z(k_all, a), cols.z(k_all, a)]),
            np.concatenate([np.full(K, uz[a]), np.full(K, -uz[a])]),
            np.concatenate([hi - ref.z[:, a], ref.z[:, a] - lo]),
        )
    for c, limit in ((0, problem.bank_rate_max), (1, problem.alpha_rate_max)):
        if limit is None:
            continue
        ineq.add(
            np.concatenate([k_all, K + k_all]),
            np.concatenate([cols.wcol(k_all, c), cols.wcol(k_all, c)]),
            np.concatenate([np.full(K, uw[c]), np.full(K, -uw[c])]),
            np.concatenate([limit - ref.w[:, c], limit + ref.w[:, c]]),
        )
    if between_points:
        _between_points(ineq, problem, ref, cols, units)
    # path limits: g + g_r dr + g_v dV + g_a dalpha - slack <= 0
    path = lin.path
    for i in range(cols.L):
        ineq.add(
            np.repeat(k_all, 4),
            np.column_stack(
                [
                    cols.z(k_all, R),
                    cols.z(k_all, V),
                    cols.z(k_all, ALPHA),
                    cols.path + i * K + k_all,
                ]
            ).ravel(),
            np.column_stack(
                [path.g_r[i] * uz[R], path.g_v[i] * uz[V], path.g_a[i] * uz[ALPHA], -np.ones(K)]
            ).ravel(),
            -path.g[i],
        )
    between = lin.between if between_points else None
    if between is not None and lin.between_owner is not None and between.g.size:
        idx, coef = pat.samples.between_idx, pat.samples.between
        owner = lin.between_owner
        n_s, width = idx.shape
        rows_s = np.repeat(np.arange(n_s), 3 * width + 1)
        for i in range(cols.L):  # the same limits between the points, on the nearest slack
            entries = np.concatenate(
                [
                    cols.z(idx, R),
                    cols.z(idx, V),
                    cols.z(idx, ALPHA),
                    (cols.path + i * K + owner)[:, None],
                ],
                axis=1,
            )
            values = np.concatenate(
                [
                    coef * (between.g_r[i] * uz[R])[:, None],
                    coef * (between.g_v[i] * uz[V])[:, None],
                    coef * (between.g_a[i] * uz[ALPHA])[:, None],
                    -np.ones((n_s, 1)),
                ],
                axis=1,
            )
            ineq.add(rows_s, entries.ravel(), values.ravel(), -between.g[i])
    # no-fly zones: distance - radius + gradient step + slack >= 0
    for i in range(cols.Z):
        ineq.add(
            np.repeat(k_all, 3),
            np.column_stack(
                [cols.z(k_all, PHI), cols.z(k_all, THETA), cols.zone + i * K + k_all]
            ).ravel(),
            np.column_stack(
                [-lin.zone_lat[i] * uz[PHI], -lin.zone_lon[i] * uz[THETA], -np.ones(K)]
            ).ravel(),
            lin.zone_c[i],
        )
    # terminal conditions on the last point: fixed ones with an L1 buffer, ranges as bounds
    last = K - 1
    cols.rows["terminal"] = ineq.count
    for j, row in enumerate(soft):
        off = row.value - ref.z[last, row.state]
        ineq.add(
            np.array([0, 0, 1, 1]),
            np.array([cols.z(last, row.state), cols.terminal + j] * 2),
            np.array([1.0, -1.0, -1.0, -1.0]),  # |dz / u - off / u| <= buffer
            np.array([off / uz[row.state], -off / uz[row.state]]),
        )
    for row in terminal:
        if row.kind != "range":
            continue
        ineq.add(
            np.array([0, 1]),
            np.array([cols.z(last, row.state)] * 2),
            np.array([uz[row.state], -uz[row.state]]),
            np.array([row.hi - ref.z[last, row.state], ref.z[last, row.state] - row.lo]),
        )
        # fixed hard rows do not occur: terminal_rows is asked for virtual buffers
    ineq.add(np.array([0]), np.array([cols.t]), np.array([-ut]), np.array([ref.tf - tf_min]))
    if hold_time:  # the final time held at the reference's
        ineq.add(np.array([0, 1]), np.array([cols.t, cols.t]), np.array([ut, -ut]), np.zeros(2))
    if box is not None:  # the hard trust region: |dz_j| <= box_j at every point, rates, t_f
        radius = np.concatenate(
            [np.tile(box / uz, K), np.full(K * NW, box_rates / uw[0]), [box_tf / ut]]
        )
        idx = np.arange(cols.steps)
        ineq.add(
            np.concatenate([idx, idx.size + idx]),
            np.concatenate([idx, idx]),
            np.concatenate([np.ones(idx.size), -np.ones(idx.size)]),
            np.concatenate([radius, radius]),
        )
    if effort:  # e_kc >= |w_kc + u_w dw_kc| / u_w: two rows per rate
        ecols = cols.effort + np.arange(K * NW)
        wcols = cols.w + np.arange(K * NW)
        rel = (ref.w / uw[None, :]).ravel()
        ineq.add(
            np.concatenate([np.arange(K * NW)] * 2 + [K * NW + np.arange(K * NW)] * 2),
            np.concatenate([wcols, ecols, wcols, ecols]),
            np.concatenate([np.ones(K * NW), -np.ones(K * NW), -np.ones(K * NW), -np.ones(K * NW)]),
            np.concatenate([-rel, rel]),
        )
    # every slack nonnegative
    first_slack = cols.nu_plus
    n_slack = cols.n - first_slack
    ineq.add(
        np.arange(n_slack),
        first_slack + np.arange(n_slack),
        -np.ones(n_slack),
        np.zeros(n_slack),
    )
    n_eq = eq.count
    cols.rows["terminal"] += n_eq  # rows counted from the first equality row
    rows = np.concatenate(eq.r + [r + n_eq for r in ineq.r])
    cols_all = np.concatenate(eq.c + ineq.c)
    vals = np.concatenate(eq.v + ineq.v)
    b = np.concatenate(eq.b + ineq.b)
    A_mat = sp.csc_matrix((vals, (rows, cols_all)), shape=(b.size, cols.n))
    q = np.zeros(cols.n)
    q[cols.t] = objective.tf * ut
    q[cols.z(last, a_idx)] += objective.final * uz
    if effort:  # C (t_f S + S_bar (t_f - t_f_bar)), S = sum W |w|: the product linearized
        weights = ref.pattern.mesh.quadrature_weights(0.0, 1.0)
        q[cols.effort : cols.effort + K * NW] = (
            objective.effort * ref.tf * (weights[:, None] * uw[None, :]).ravel()
        )
        q[cols.t] += objective.effort * float(weights @ np.sum(np.abs(ref.w), axis=1)) * ut
    q[first_slack : cols.terminal] = weight_virtual
    # a fixed condition's buffer is virtual control; a soft condition costs its own weight
    q[cols.terminal :] = [weight_virtual if t.virtual else t.weight for t in soft]
    diag = np.zeros(cols.n)
    diag[: cols.steps] = weight_trust
    if rate_weight > 0.0:  # rate_weight * mean((w / unit)^2): a quadratic in the rate changes
        per = rate_weight / K
        wcols = cols.wcol(k_all[:, None], c_idx[None, :])
        diag[wcols] += 2.0 * per
        q[wcols] += 2.0 * per * ref.w / uw[None, :]
    P = sp.diags(diag, format="csc")
    if curvature is not None:  # the Lagrangian's convexified blocks on (z_j, w_j)
        cols10 = np.concatenate(
            [cols.z(k_all[:, None], a_idx[None, :]), cols.wcol(k_all[:, None], c_idx[None, :])],
            axis=1,
        )  # (K, 10)
        rows10 = np.repeat(cols10[:, :, None], 10, axis=2).ravel()
        cols10_b = np.repeat(cols10[:, None, :], 10, axis=1).ravel()
        P = P + sp.csc_matrix((curvature.ravel(), (rows10, cols10_b)), shape=(cols.n, cols.n))
        P = sp.triu(P, format="csc")  # Clarabel reads the upper triangle
    return ConeProblem(P, q, A_mat, b, ConeSpec(n_eq, b.size - n_eq)), cols


def _between_points(
    ineq: _Rows, problem: EntryProblem, ref: HpIterate, cols: Columns, units: Units
) -> None:
    """Bank and alpha as the flight sees them, their interval polynomials, within their bounds
    and rate bounds everywhere, through the Bernstein coefficients of the polynomials and of
    their derivatives (``PolynomialSamples``; the rate rows |g x| <= r t_f are linear in the
    point values and t_f)."""
    samples = ref.pattern.samples
    uz, ut = units.z, units.t
    value_bounds = [(SIGMA, problem.bank_min, problem.bank_max)]
    if problem.alpha_range is not None:
        value_bounds.append((ALPHA, *problem.alpha_range))
    idx, hull = samples.hull_idx, samples.hull
    n_v = idx.shape[0]
    for a, lo, hi in value_bounds:
        if not n_v:
            break
        at = np.sum(hull * ref.z[idx, a], axis=1)
        columns = cols.z(idx, a)
        coef = hull * uz[a]
        rows = np.repeat(np.arange(n_v), columns.shape[1])
        ineq.add(
            np.concatenate([rows, n_v + rows]),
            np.concatenate([columns.ravel(), columns.ravel()]),
            np.concatenate([coef.ravel(), -coef.ravel()]),
            np.concatenate([hi - at, at - lo]),
        )
    idx, slope_map = samples.slope_idx, samples.slope
    n_r = idx.shape[0]
    for a, limit in ((SIGMA, problem.bank_rate_max), (ALPHA, problem.alpha_rate_max)):
        if limit is None:
            continue
        slope = np.sum(slope_map * ref.z[idx, a], axis=1)
        columns = cols.z(idx, a)
        width = columns.shape[1]
        coef = slope_map * uz[a]
        rows = np.repeat(np.arange(n_r), width + 1)
        tcol = np.full((n_r, 1), cols.t)
        tcoef = np.full((n_r, 1), -limit * ut)
        ineq.add(
            np.concatenate([rows, n_r + rows]),
            np.concatenate([np.hstack([columns, tcol]).ravel()] * 2),
            np.concatenate([np.hstack([coef, tcoef]).ravel(), np.hstack([-coef, tcoef]).ravel()]),
            np.concatenate([limit * ref.tf - slope, limit * ref.tf + slope]),
        )


def model_curvature(P: sp.spmatrix | None, x: Array, weight_trust: float, steps: int) -> float:
    """The quadratic part of a step's model of the penalized cost: 1/2 x'Px of the subproblem's
    upper-triangular P less the trust penalty on the first ``steps`` columns, i.e. the rate
    regularization and the Lagrangian's curvature. The predicted decrease must count it: for a
    Newton-like step the linear part alone predicts twice the decrease the quadratic model
    does, and the ratio test would hold the trust weight on a model that is right."""
    if P is None:
        return 0.0
    full = 0.5 * float(x @ (P @ x) + x @ (P.T @ x) - P.diagonal() @ (x * x))
    head = x[:steps]
    return full - 0.5 * weight_trust * float(head @ head)


def slacked_multipliers(y: Array, cols: Columns, weight: float) -> float:
    """The largest multiplier of a row the virtual control relaxes (scaled units): collocation
    rows; path and zone rows, by slack (the total of the rows that share it, ``weight`` less
    the multiplier of its sign row); and each fixed terminal condition (the difference of its
    two one-sided rows' multipliers: at a met condition both rows are active and an
    interior-point solver splits the weight between them, so neither alone is the condition's
    multiplier). The exact L1 penalty needs a weight above it (Nocedal & Wright, sec. 17.2)."""
    largest = float(np.max(np.abs(y[: cols.collocation_rows]))) if cols.K > 1 else 0.0
    n_slack = cols.n - cols.nu_plus
    signs = y[y.size - n_slack :]  # the slacks' sign rows, in column order
    shared = signs[cols.path - cols.nu_plus : cols.terminal - cols.nu_plus]
    if shared.size:
        largest = max(largest, weight - float(np.min(shared)))
    t0 = cols.rows["terminal"]
    if cols.T:
        pairs = y[t0 : t0 + 2 * cols.T]
        largest = max(largest, float(np.max(np.abs(pairs[0::2] - pairs[1::2]))))
    return largest


def effort_integral(ref: HpIterate) -> float:
    """t_f sum_k W_k (|alpha'_k| + |sigma'_k|): the integral of the rates' magnitudes over the
    flight (rad; the mesh's composite Clenshaw-Curtis weights W on [0, 1])."""
    weights = ref.pattern.mesh.quadrature_weights(0.0, 1.0)
    return ref.tf * float(weights @ np.sum(np.abs(ref.w), axis=1))


def step_of(x: Array, cols: Columns, units: Units) -> tuple[Array, Array, float]:
    """(dz (K, 8), dw (K, 2), dt_f) in nondimensional units from a solution."""
    K = cols.K
    dz = x[: K * NZ].reshape(K, NZ) * units.z
    dw = x[cols.w : cols.t].reshape(K, NW) * units.w
    return dz, dw, float(x[cols.t] * units.t)
