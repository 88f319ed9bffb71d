"""The LGL collocation NLP of a phased flight (paper 004 sec. 2.1): variables, bounds, constraint
rows with their sparse Jacobian, the objective, and the Lagrangian's Hessian blocks.

Variables per phase: the states and controls at every LGL point of its segments and its
duration (``transcription.lgl``: integral-form collocation, x_j = x_0 + tau (b - a)/2 sum_l A_jl
f_l on a segment [a, b] of the normalized phase time). All work is in scaled variables
z = S z_s (``Layout.scale``), so a unit step is a large one in every component. Rows:
equalities (collocation defects and phase linkage, scaled by the state scales; fixed end
conditions) and inequalities <= 0 (path limits as value / limit - 1, range end conditions).
Rates are differentiated by central differences over all points at once, the Lagrangian's
second derivatives by second differences per point (exact to the differencing error, about
1e-8 of the scales): the per-point blocks of an exact Hessian.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from worker.solver.models.powered import PoweredModel, path_ratios
from worker.solver.objective_weights import term_pulls
from worker.solver.phased_problem import PhasedProblem
from worker.solver.trajectory import TIME_STATE_NAMES
from worker.solver.transcription.lgl import LglMesh, integration_matrix

Array = np.ndarray

STATE_SCALES = (0.02, 0.2, 0.2, 0.2, 0.2, 0.2, 0.1)
"""Scaled unit of each state: r (128 km on Earth), theta, phi (11.5 deg), V (1.6 km/s), gamma
(11.5 deg), psi, mass (10 % of m0); the thrust's is the largest thrust. Units near each state's
excursion over an entry: the trust box is one number for all, and a state with a small unit
(the flight-path angle at 1.1 deg, as first chosen) held every step to a few hundredths of a
degree: paper 004's case took 250-600 iterations from a GA/PSO guess, 100-180 with these."""
ANGLE_SCALES = (0.2, 0.5)
"""Scaled unit of alpha and bank, rad."""
DURATION_SCALE = 0.5
"""Scaled unit of a phase's duration: this share of its longest duration."""
FD_STEP = 1e-6
"""Central-difference step of the rates' Jacobians, in scaled units."""
FD_STEP_2 = 1e-4
"""Second-difference step of the Hessian blocks, in scaled units."""
R_MAX_ALTITUDE_M = 1.0e6
SPEED_MIN = 1e-3
GAMMA_MAX = math.radians(85.0)
LAT_MAX = math.radians(89.0)
DYNAMICS_WEIGHT = 10.0
"""Elastic penalty of the defects and linkage rows relative to the end and path rows: when no
trajectory meets every condition, the end conditions give way, not the physics, so the failure
names them."""

OBJECTIVE_UNITS = {
    "min_propellant": 0.01,  # of the initial mass, kg
    "min_time": 100.0,  # s
    "max_terminal_velocity": 100.0,  # m/s
    "max_final_latitude": 1.0,  # deg
    "min_final_latitude": 1.0,
    "max_final_longitude": 1.0,
    "min_final_longitude": 1.0,
}
"""Each supported objective term's normalized unit (SI and degrees)."""


@dataclass
class PhaseSlots:
    """Where one phase's variables sit in z: its states (points x n_states, row-major), its
    controls and its duration."""

    mesh: LglMesh
    x0: int
    u0: int
    tau: int


@dataclass
class RowInfo:
    """What each constraint row is, for reports: kind, phase, quantity and point."""

    kind: list[str] = field(default_factory=list)
    phase: list[int] = field(default_factory=list)
    name: list[str] = field(default_factory=list)
    point: list[int] = field(default_factory=list)

    def add(self, kind: str, phase: int, names: list[str], points: list[int]) -> None:
        self.kind += [kind] * len(names)
        self.phase += [phase] * len(names)
        self.name += names
        self.point += points


@dataclass
class Evaluation:
    """The NLP at one point: objective (normalized) and its gradient, equality and inequality
    values, their Jacobians (scaled variables), and what the Hessian needs."""

    objective: float
    gradient: Array
    eq: Array
    ineq: Array
    jac_eq: sp.csr_matrix
    jac_ineq: sp.csr_matrix
    points: list[tuple[Array, Array]]  # per phase (states, controls) at its points


class PhasedNlp:
    """The collocation NLP of ``problem`` on one mesh per phase."""

    def __init__(self, problem: PhasedProblem, meshes: list[LglMesh]) -> None:
        self.problem = problem
        self.model: PoweredModel = problem.model
        self.meshes = meshes
        nx, nu = self.model.n_states, self.model.n_controls
        self.nx, self.nu = nx, nu
        slots, at = [], 0
        for mesh in meshes:
            x0 = at
            u0 = x0 + mesh.points * nx
            tau = u0 + mesh.points * nu
            slots.append(PhaseSlots(mesh, x0, u0, tau))
            at = tau + 1
        self.slots = slots
        self.n = at
        thr = self.model.thruster
        tmax = thr.max_thrust if thr is not None and thr.max_thrust > 0 else 1.0
        self.state_scale = np.array([*STATE_SCALES, tmax][:nx])
        self.control_scale = np.array([*ANGLE_SCALES, tmax][:nu])
        scale = np.empty(self.n)
        for s, ph in zip(slots, problem.phases, strict=True):
            scale[s.x0 : s.u0] = np.tile(self.state_scale, s.mesh.points)
            scale[s.u0 : s.tau] = np.tile(self.control_scale, s.mesh.points)
            scale[s.tau] = DURATION_SCALE * ph.duration_max
        self.scale = scale
        self.lower, self.upper = self._bounds()
        self._objective_setup()
        self.eq_info, self.ineq_info = RowInfo(), RowInfo()
        self._describe_rows()

    # ----------------------------------------------------------------- layout
    def states(self, z: Array, p: int) -> Array:
        s = self.slots[p]
        return z[s.x0 : s.u0].reshape(s.mesh.points, self.nx)

    def controls(self, z: Array, p: int) -> Array:
        s = self.slots[p]
        return z[s.u0 : s.tau].reshape(s.mesh.points, self.nu)

    def duration(self, z: Array, p: int) -> float:
        return float(z[self.slots[p].tau])

    def pack(self, xs: list[Array], us: list[Array], taus: list[float]) -> Array:
        """z of each phase's states, controls and duration."""
        z = np.empty(self.n)
        for s, x, u, tau in zip(self.slots, xs, us, taus, strict=True):
            z[s.x0 : s.u0] = x.ravel()
            z[s.u0 : s.tau] = u.ravel()
            z[s.tau] = tau
        return z

    def describe_variable(self, i: int) -> str:
        """Which variable index ``i`` of z is, e.g. 'exit u2 @ 17' (phase, state x / control u and
        its index, point) or 'descent duration'."""
        for p, s in enumerate(self.slots):
            name = self.problem.phases[p].name
            if s.x0 <= i < s.u0:
                return f"{name} x{(i - s.x0) % self.nx} @ {(i - s.x0) // self.nx}"
            if s.u0 <= i < s.tau:
                return f"{name} u{(i - s.u0) % self.nu} @ {(i - s.u0) // self.nu}"
            if i == s.tau:
                return f"{name} duration"
        raise IndexError(i)

    # ----------------------------------------------------------------- bounds
    def _bounds(self) -> tuple[Array, Array]:
        pb = self.problem
        lo, hi = np.full(self.n, -np.inf), np.full(self.n, np.inf)
        thr = self.model.thruster
        sx_lo = np.full(self.nx, -np.inf)
        sx_hi = np.full(self.nx, np.inf)
        sx_lo[0], sx_hi[0] = 1.0, 1.0 + R_MAX_ALTITUDE_M / pb.base.scales.radius_m
        sx_lo[2], sx_hi[2] = -LAT_MAX, LAT_MAX
        sx_lo[3] = SPEED_MIN
        sx_lo[4], sx_hi[4] = -GAMMA_MAX, GAMMA_MAX
        if thr is not None:
            sx_lo[6] = thr.dry_mass if thr.dry_mass is not None else 1e-3
            sx_hi[6] = 1.0
            if thr.lagged:
                sx_lo[7], sx_hi[7] = 0.0, thr.max_thrust
        unpowered = thr is not None and thr.initial_thrust == 0.0  # no thrust so far
        for p, (s, ph) in enumerate(zip(self.slots, pb.phases, strict=True)):
            npt = s.mesh.points
            lo[s.x0 : s.u0] = np.tile(sx_lo, npt)
            hi[s.x0 : s.u0] = np.tile(sx_hi, npt)
            unpowered = unpowered and ph.thrust_max == 0.0
            if unpowered:  # a coast before any burn: mass and thrust stay at their start
                for i in range(6, self.nx):
                    lo[s.x0 + i : s.u0 : self.nx] = pb.x0[i]
                    hi[s.x0 + i : s.u0 : self.nx] = pb.x0[i]
            ulo = [ph.alpha_range[0], ph.bank_range[0]]
            uhi = [ph.alpha_range[1], ph.bank_range[1]]
            if self.nu == 3:
                ulo.append(0.0)
                uhi.append(ph.thrust_max)
            lo[s.u0 : s.tau] = np.tile(ulo, npt)
            hi[s.u0 : s.tau] = np.tile(uhi, npt)
            lo[s.tau], hi[s.tau] = ph.duration_min, ph.duration_max
            if p == 0:
                lo[s.x0 : s.x0 + self.nx] = pb.x0
                hi[s.x0 : s.x0 + self.nx] = pb.x0
        return lo, hi

    # ----------------------------------------------------------------- objective
    def _objective_setup(self) -> None:
        pb = self.problem
        sc = pb.base.scales
        last = self.slots[-1]
        end = last.x0 + (last.mesh.points - 1) * self.nx  # the final state's first entry
        terms = pb.base.objective
        units = {
            t.name: OBJECTIVE_UNITS[t.name] * (pb.mass_kg if t.name == "min_propellant" else 1.0)
            for t in terms
        }
        pulls = term_pulls([t.weight for t in terms], [units[t.name] for t in terms])
        g = np.zeros(self.n)
        self.term_gradients: dict[str, Array] = {}
        self.term_offsets: dict[str, float] = {}
        for term, pull in zip(terms, pulls, strict=True):
            tg = np.zeros(self.n)  # d(value in SI) / dz
            offset = 0.0
            if term.name == "min_propellant":
                tg[end + 6] = -pb.mass_kg
                offset = pb.mass_kg
            elif term.name == "min_time":
                for s in self.slots:
                    tg[s.tau] = sc.time_s
            elif term.name == "max_terminal_velocity":
                tg[end + 3] = sc.speed_m_s
            elif term.name.endswith("latitude"):
                tg[end + 2] = math.degrees(1.0)
            elif term.name.endswith("longitude"):
                tg[end + 1] = math.degrees(1.0)
            else:  # refused by the support check
                raise ValueError(f"lgl-sqp cannot optimize {term.name!r}")
            self.term_gradients[term.name] = tg
            self.term_offsets[term.name] = offset
            sign = -1.0 if term.name.startswith("max") else 1.0
            g += sign * pull / units[term.name] * tg
        self.objective_gradient = g  # normalized objective, physical variables
        self.objective_offset = sum(
            (-1.0 if t.name.startswith("max") else 1.0) * p / units[t.name]
            * self.term_offsets[t.name]
            for t, p in zip(terms, pulls, strict=True)
        )  # fmt: skip

    def objective_terms(self, z: Array) -> dict[str, float]:
        """Each objective term's value in its SI unit (kg, s, m/s, deg)."""
        return {
            name: float(tg @ z + self.term_offsets[name])
            for name, tg in self.term_gradients.items()
        }

    # ----------------------------------------------------------------- rows
    def _end_rows(self, p: int) -> list[tuple[str, str, int, float]]:
        """(kind, name, state index, value): fixed end conditions as 'eq', ranges as two
        'hi'/'lo' inequalities."""
        ph = self.problem.phases[p]
        rows = []
        for i, name in enumerate(TIME_STATE_NAMES):
            t = ph.end[name]
            if t.kind == "fixed":
                assert t.value is not None
                rows.append(("eq", name, i, t.value))
            elif t.kind == "range":
                assert t.lo is not None and t.hi is not None
                rows.append(("hi", name, i, t.hi))
                rows.append(("lo", name, i, t.lo))
        return rows

    def _describe_rows(self) -> None:
        for p, s in enumerate(self.slots):
            n, segs = s.mesh.degree, s.mesh.segments
            pts = [k * n + j for k in range(segs) for j in range(1, n + 1) for _ in range(self.nx)]
            names = [f"defect:{i}" for _ in range(segs * n) for i in range(self.nx)]
            self.eq_info.add("defect", p, names, pts)
            if p > 0:
                self.eq_info.add("linkage", p, [f"linkage:{i}" for i in range(self.nx)],
                                 [0] * self.nx)  # fmt: skip
            last = s.mesh.points - 1
            for kind, name, _, _ in self._end_rows(p):
                info = self.eq_info if kind == "eq" else self.ineq_info
                info.add("end", p, [f"{name}:{kind}"], [last])
            limit_names = self._limit_names(p)
            self.ineq_info.add(
                "path", p, [nm for _ in range(s.mesh.points) for nm in limit_names],
                [j for j in range(s.mesh.points) for _ in limit_names],
            )  # fmt: skip

    def _limit_names(self, p: int) -> list[str]:
        lim = self.problem.phases[p].limits
        names = []
        if lim.heat_max_W_m2 is not None and lim.heat is not None:
            names.append("heat_rate")
        if lim.dynamic_pressure_max_Pa is not None:
            names.append("dynamic_pressure")
        if lim.load_factor_max_g is not None:
            names.append("load_factor")
        return names

    # ----------------------------------------------------------------- derivatives
    def _node_functions(self, p: int, x: Array, u: Array) -> tuple[Array, Array]:
        """Rates (M, nx) and path ratios - 1 (M, k) at rows of (x, u)."""
        f = self.model.rates(x, u)
        g = path_ratios(self.model, self.problem.phases[p].limits, x, u) - 1.0
        return f, g

    def _point_jacobians(self, p: int, x: Array, u: Array) -> tuple[Array, Array, Array, Array]:
        """f, g at the points and their Jacobians in the point's scaled (x, u)."""
        npt = x.shape[0]
        nv = self.nx + self.nu
        scale = np.concatenate([self.state_scale, self.control_scale])
        w = np.concatenate([x, u], axis=1)
        steps = FD_STEP * scale
        pert = np.repeat(w[None, :, :], 2 * nv, axis=0)  # (2nv, npt, nv)
        for v in range(nv):
            pert[2 * v, :, v] += steps[v]
            pert[2 * v + 1, :, v] -= steps[v]
        flat = pert.reshape(-1, nv)
        f_all, g_all = self._node_functions(p, flat[:, : self.nx], flat[:, self.nx :])
        f_all = f_all.reshape(2 * nv, npt, self.nx)
        g_all = g_all.reshape(2 * nv, npt, -1)
        jf = (f_all[0::2] - f_all[1::2]) / (2.0 * FD_STEP)  # (nv, npt, nx), d/d scaled var
        jg = (g_all[0::2] - g_all[1::2]) / (2.0 * FD_STEP)
        f, g = self._node_functions(p, x, u)
        return f, g, np.transpose(jf, (1, 2, 0)), np.transpose(jg, (1, 2, 0))

    def evaluate(self, z: Array) -> Evaluation:
        """Objective, rows and Jacobians at ``z`` (physical variables)."""
        nx, nu = self.nx, self.nu
        nv = nx + nu
        eq_vals: list[Array] = []
        eq_r: list[Array] = []
        eq_c: list[Array] = []
        eq_v: list[Array] = []
        in_vals: list[Array] = []
        in_r: list[Array] = []
        in_c: list[Array] = []
        in_v: list[Array] = []
        n_eq = n_in = 0
        points = []
        sx = self.state_scale
        for p, s in enumerate(self.slots):
            mesh = s.mesh
            n, segs = mesh.degree, mesh.segments
            x, u = self.states(z, p), self.controls(z, p)
            tau = self.duration(z, p)
            points.append((x, u))
            f, g, jf, jg = self._point_jacobians(p, x, u)
            A = integration_matrix(n)[1:]  # (n, n+1)
            half = 0.5 * np.diff(mesh.breaks)  # (segs,)
            idx = np.arange(segs)[:, None] * n + np.arange(n + 1)[None, :]  # (segs, n+1)
            fs = f[idx]  # (segs, n+1, nx)
            integral = np.einsum("jl,kli->kji", A, fs)  # (segs, n, nx)
            xs = x[idx]
            defect = (xs[:, 1:, :] - xs[:, :1, :] - tau * half[:, None, None] * integral) / sx
            eq_vals.append(defect.ravel())
            rows = n_eq + np.arange(segs * n * nx).reshape(segs, n, nx)
            n_eq += segs * n * nx
            # d defect / d (x_l, u_l) in scaled variables
            jseg = jf[idx]  # (segs, n+1, nx, nv)
            val = (
                -(tau * half)[:, None, None, None, None]
                * A[None, :, None, :, None]
                * (np.transpose(jseg, (0, 2, 1, 3))[:, None, :, :, :])
            )  # (segs, n, nx, n+1, nv)
            val = val / sx[None, None, :, None, None]
            ident = np.zeros((n, n + 1))
            ident[np.arange(n), np.arange(1, n + 1)] = 1.0
            ident[:, 0] -= 1.0
            eye = np.zeros((nx, nv))
            eye[np.arange(nx), np.arange(nx)] = 1.0
            val = val + ident[None, :, None, :, None] * eye[None, None, :, None, :]
            col_x = s.x0 + idx[:, :, None] * nx + np.arange(nx)[None, None, :]  # (segs, n+1, nx)
            col_u = s.u0 + idx[:, :, None] * nu + np.arange(nu)[None, None, :]
            cols = np.concatenate([col_x, col_u], axis=2)  # (segs, n+1, nv)
            R = np.broadcast_to(rows[:, :, :, None, None], val.shape)
            C = np.broadcast_to(cols[:, None, None, :, :], val.shape)
            eq_r.append(R.ravel())
            eq_c.append(C.ravel())
            eq_v.append(val.ravel())
            # d defect / d tau (scaled)
            dtau = -(half[:, None, None] * integral) / sx * self.scale[s.tau]
            eq_r.append(rows.ravel())
            eq_c.append(np.full(rows.size, s.tau))
            eq_v.append(dtau.ravel())
            if p > 0:  # linkage: this phase's first state = the previous phase's last
                prev = self.slots[p - 1]
                xp = self.states(z, p - 1)[-1]
                eq_vals.append((x[0] - xp) / sx)
                r = n_eq + np.arange(nx)
                n_eq += nx
                first = s.x0 + np.arange(nx)
                lastp = prev.x0 + (prev.mesh.points - 1) * nx + np.arange(nx)
                eq_r += [r, r]
                eq_c += [first, lastp]
                eq_v += [np.ones(nx), -np.ones(nx)]
            last = s.x0 + (mesh.points - 1) * nx
            for kind, _, i, value in self._end_rows(p):
                unit = sx[i]
                if kind == "eq":
                    eq_vals.append(np.array([(x[-1, i] - value) / unit]))
                    eq_r.append(np.array([n_eq]))
                    n_eq += 1
                    eq_c.append(np.array([last + i]))
                    eq_v.append(np.array([1.0]))
                else:
                    sign = 1.0 if kind == "hi" else -1.0
                    in_vals.append(np.array([sign * (x[-1, i] - value) / unit]))
                    in_r.append(np.array([n_in]))
                    n_in += 1
                    in_c.append(np.array([last + i]))
                    in_v.append(np.array([sign]))
            k = g.shape[1]
            if k:
                in_vals.append(g.ravel())
                rows_g = n_in + np.arange(mesh.points * k).reshape(mesh.points, k)
                n_in += mesh.points * k
                colsp = np.concatenate(
                    [
                        s.x0 + np.arange(mesh.points)[:, None] * nx + np.arange(nx)[None, :],
                        s.u0 + np.arange(mesh.points)[:, None] * nu + np.arange(nu)[None, :],
                    ],
                    axis=1,
                )  # (points, nv)
                in_r.append(np.broadcast_to(rows_g[:, :, None], (mesh.points, k, nv)).ravel())
                in_c.append(np.broadcast_to(colsp[:, None, :], (mesh.points, k, nv)).ravel())
                in_v.append(jg.ravel())
        jac_eq = sp.csr_matrix(
            (np.concatenate(eq_v), (np.concatenate(eq_r), np.concatenate(eq_c))),
            shape=(n_eq, self.n),
        )
        if in_r:
            jac_in = sp.csr_matrix(
                (np.concatenate(in_v), (np.concatenate(in_r), np.concatenate(in_c))),
                shape=(n_in, self.n),
            )
        else:
            jac_in = sp.csr_matrix((0, self.n))
        return Evaluation(
            objective=float(self.objective_gradient @ z + self.objective_offset),
            gradient=self.objective_gradient * self.scale,
            eq=np.concatenate(eq_vals),
            ineq=np.concatenate(in_vals) if in_vals else np.zeros(0),
            jac_eq=jac_eq,
            jac_ineq=jac_in,
            points=points,
        )

    def largest_defect(self, ev: Evaluation) -> float:
        """The largest dynamics row of ``ev`` in absolute value (scaled units)."""
        dyn = np.array([k != "end" for k in self.eq_info.kind])
        eq = np.abs(ev.eq[dyn])
        return float(np.max(eq)) if eq.size else 0.0

    def violation(self, ev: Evaluation) -> tuple[float, float]:
        """(l1 of the dynamics rows, l1 of the end and path rows' excess)."""
        dyn = np.array([k != "end" for k in self.eq_info.kind])
        eq = np.abs(ev.eq)
        ineq = np.maximum(ev.ineq, 0.0)
        return float(eq[dyn].sum()), float(eq[~dyn].sum() + ineq.sum())

    # ----------------------------------------------------------------- Hessian
    def hessian(self, z: Array, ev: Evaluation, lam_eq: Array, lam_in: Array) -> sp.csc_matrix:
        """The Lagrangian's Hessian in scaled variables, per-point blocks made positive
        definite (eigenvalues clipped), the durations' diagonal regularized; upper triangle."""
        nx, nu = self.nx, self.nu
        blocks_r, blocks_c, blocks_v = [], [], []

        def cols_of(slot: PhaseSlots, points: int) -> Array:
            return _cols(nx, nu, slot, points)

        row_eq = 0
        row_in = 0
        sx = self.state_scale
        for p, s in enumerate(self.slots):
            mesh = s.mesh
            n, segs = mesh.degree, mesh.segments
            x, u = ev.points[p]
            tau = self.duration(z, p)
            A = integration_matrix(n)[1:]
            half = 0.5 * np.diff(mesh.breaks)
            lam = lam_eq[row_eq : row_eq + segs * n * nx].reshape(segs, n, nx)
            row_eq += segs * n * nx + (nx if p > 0 else 0)
            row_eq += sum(1 for k, *_ in self._end_rows(p) if k == "eq")
            # weight of f_i at each point: -tau (b-a)/2 sum_j A_jl lam_kji / s_i
            wseg = -(tau * half)[:, None, None] * np.einsum("jl,kji->kli", A, lam) / sx
            mu = np.zeros((mesh.points, nx))
            idx = np.arange(segs)[:, None] * n + np.arange(n + 1)[None, :]
            np.add.at(mu, idx, wseg)
            row_in += sum(1 for k, *_ in self._end_rows(p) if k != "eq")
            k = len(self._limit_names(p))
            nu_g = lam_in[row_in : row_in + mesh.points * k].reshape(mesh.points, k)
            row_in += mesh.points * k
            H = self._point_hessians(p, x, u, mu, nu_g)  # (points, nv, nv) scaled
            H = _clip_psd(H)
            cols = np.concatenate(
                [
                    s.x0 + np.arange(mesh.points)[:, None] * nx + np.arange(nx)[None, :],
                    s.u0 + np.arange(mesh.points)[:, None] * nu + np.arange(nu)[None, :],
                ],
                axis=1,
            )
            blocks_r.append(np.broadcast_to(cols[:, :, None], H.shape).ravel())
            blocks_c.append(np.broadcast_to(cols[:, None, :], H.shape).ravel())
            blocks_v.append(H.ravel())
        r = np.concatenate(blocks_r)
        c = np.concatenate(blocks_c)
        v = np.concatenate(blocks_v)
        H = sp.coo_matrix((v, (r, c)), shape=(self.n, self.n)).tocsc()
        return H

    def _point_hessians(self, p: int, x: Array, u: Array, mu: Array, nu_g: Array) -> Array:
        """Second differences of mu . f + nu . g at each point, in scaled (x, u)."""
        nv = self.nx + self.nu
        scale = np.concatenate([self.state_scale, self.control_scale])
        w = np.concatenate([x, u], axis=1)
        h = FD_STEP_2
        offsets = [np.zeros(nv)]
        pairs = []
        for a in range(nv):
            e = np.zeros(nv)
            e[a] = h
            offsets += [e, -e]
        for a in range(nv):
            for b in range(a + 1, nv):
                ea = np.zeros(nv)
                ea[a] = h
                eb = np.zeros(nv)
                eb[b] = h
                pairs.append((a, b, len(offsets)))
                offsets += [ea + eb, ea - eb, -ea + eb, -ea - eb]
        off = np.array(offsets) * scale  # (P, nv) physical
        pert = w[None, :, :] + off[:, None, :]  # (P, points, nv)
        flat = pert.reshape(-1, nv)
        f, g = self._node_functions(p, flat[:, : self.nx], flat[:, self.nx :])
        P = off.shape[0]
        phi = np.einsum("pmi,mi->pm", f.reshape(P, -1, self.nx), mu)
        if g.shape[1]:
            phi = phi + np.einsum("pmk,mk->pm", g.reshape(P, -1, g.shape[1]), nu_g)
        H = np.zeros((w.shape[0], nv, nv))
        for a in range(nv):
            H[:, a, a] = (phi[1 + 2 * a] - 2.0 * phi[0] + phi[2 + 2 * a]) / (h * h)
        for a, b, i in pairs:
            val = (phi[i] - phi[i + 1] - phi[i + 2] + phi[i + 3]) / (4.0 * h * h)
            H[:, a, b] = val
            H[:, b, a] = val
        return H


def _cols(nlp_nx: int, nlp_nu: int, s: PhaseSlots, points: int) -> Array:
    """(points, nv) column of each point's states and controls in z."""
    return np.concatenate(
        [
            s.x0 + np.arange(points)[:, None] * nlp_nx + np.arange(nlp_nx)[None, :],
            s.u0 + np.arange(points)[:, None] * nlp_nu + np.arange(nlp_nu)[None, :],
        ],
        axis=1,
    )


def _clip_psd(H: Array, floor: float = 0.0) -> Array:
    """Each symmetric block with its eigenvalues raised to ``floor`` (convexified)."""
    vals, vecs = np.linalg.eigh(H)
    vals = np.maximum(vals, floor)
    return np.einsum("mij,mj,mkj->mik", vecs, vals, vecs)
