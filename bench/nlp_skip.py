"""An independent NLP of a flight in phases with thrust (paper 004's skip entry), for side by side
runs against ``lgl-sqp``.

Hermite–Simpson collocation in separated form (states and controls at the nodes and at the
interval midpoints; Betts, Practical Methods for Optimal Control, 2nd ed., sec. 4.6.4) of every
phase on its own uniform mesh of its normalized time, the phases linked by continuity of the
whole state, solved by IPOPT (MUMPS) through CasADi Opti. The problem is read through
``build_phased_problem``: the phases' duration bounds, end conditions (fixed and soft ones held
hard, ranges as bounds), angle-of-attack, bank and thrust bounds and path limits (heat rate with
its angle-of-attack factor, dynamic pressure, load factor at every node and midpoint), the dry
mass, the initial state and the objective ``min_propellant``.

The physics are written out here in CasADi symbols, not taken from the solver: the point-mass
equations over a spherical planet (rotating or not) with lift and drag replaced by
(L + T sin alpha) / m and (D - T cos alpha) / m (thrust along the body axis), mass flow
-T / (Isp g_std) and the first-order thrust lag, in the nondimensional units of
``units.Scales``; polynomial CL(alpha) and CD(alpha) or CD(CL); an exponential or US76
atmosphere. For US76, ln(rho) is the same monotone cubic (PCHIP) through the US76 densities at
the altitude nodes the solver tabulates, continued linearly beyond them, held as a cubic
B-spline with double interior knots (a CasADi ``bspline`` function): the two densities agree to
rounding. ``tests/unit/test_nlp_skip_rates.py`` checks the rates against the solver's
``PoweredModel.rates``.

The initial guess is one forward propagation (RK4, 1 s steps) of every phase with constant
controls: alpha 40 deg and bank 40 deg (clipped to the phase's bounds) and the phase's largest
thrust, each phase starting where the previous one ended and flown until it crosses its fixed
end altitude (within its duration bounds; the middle of the bounds flies into the ground).

On ``shuttle-skip-min-propellant`` the answer moves with the exit phase's mesh, whose burn of
about 14 s against a 1 s thrust lag is resolved by a few intervals: 9087.02 kg at 150 + 50
intervals, 9086.26 at 150 + 100, 9085.96 at 150 + 150, 9086.18 at 150 + 320 or 800 + 320
(the descent's mesh barely matters), all within 0.015 % of the reference.

    pip install -e '.[bench]'   # CasADi
    python -m bench.nlp_skip [--intervals 150 50] [--scenario shuttle-skip-min-propellant]

CasADi is an optional benchmark dependency; nothing in the service imports this module.
"""

from __future__ import annotations

import argparse
import copy
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from app.schemas import ProblemDocument
from worker.solver.aero_models import PolynomialAero
from worker.solver.atmosphere import ExponentialAtmosphere, US76Atmosphere, _us76_grid
from worker.solver.path_limits import PathLimits
from worker.solver.phased_problem import PhasedProblem, build_phased_problem
from worker.solver.scenarios import get_scenario
from worker.solver.trajectory import TIME_STATE_NAMES

SCENARIO = "shuttle-skip-min-propellant"
REFERENCE_PROPELLANT_KG = 9085.75
"""The scenario's independent reference (800 + 320 Hermite–Simpson intervals)."""
DEFAULT_INTERVALS = (150, 50)
GUESS_ALPHA_DEG = 40.0
GUESS_BANK_DEG = 40.0
GUESS_STEP_S = 1.0
"""RK4 step of the guess's propagation, s."""
R_MAX_ALTITUDE_M = 1.0e6
"""Highest altitude a point may take (the top of the US76 table)."""
SPEED_MIN = 1e-3
"""Smallest nondimensional speed a point may take (the equations divide by it)."""
US76_EXTENSION_M = (-100e3, 5000e3)
"""Altitudes to which the B-spline of ln(rho) carries the table's linear continuation."""


def _poly(coefficients: Sequence[float], x: Any) -> Any:
    """sum c_k x^k (lowest order first) by Horner's rule, on a number or a CasADi symbol."""
    value: Any = float(coefficients[-1])
    for c in reversed(coefficients[:-1]):
        value = value * x + float(c)
    return value


def pchip_bspline(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Knots and coefficients of the cubic B-spline equal to the PCHIP interpolant of y(x), its
    two end segments extended linearly to ``US76_EXTENSION_M`` (as the solver's table)."""
    from scipy.interpolate import PchipInterpolator

    f = PchipInterpolator(x, y, extrapolate=False)
    d = f.derivative()(x)
    lo, hi = US76_EXTENSION_M
    x = np.concatenate([[lo], x, [hi]])
    y = np.concatenate([[y[0] + d[0] * (lo - x[1])], y, [y[-1] + d[-1] * (hi - x[-2])]])
    d = np.concatenate([[d[0]], d, [d[-1]]])
    h = np.diff(x)
    # a C1 cubic with double interior knots: its B-spline coefficients are the inner Bezier
    # points of each segment, f_i + h d_i / 3 and f_{i+1} - h d_{i+1} / 3
    inner = np.column_stack([y[:-1] + h * d[:-1] / 3.0, y[1:] - h * d[1:] / 3.0]).ravel()
    coefficients = np.concatenate([[y[0]], inner, [y[-1]]])
    knots = np.concatenate([[x[0]] * 4, np.repeat(x[1:-1], 2), [x[-1]] * 4])
    return knots, coefficients


class CasadiPowered:
    """The powered point-mass dynamics and path quantities of a phased problem in CasADi symbols
    (nondimensional states and controls, as ``models.powered.PoweredModel``)."""

    def __init__(self, problem: PhasedProblem) -> None:
        import casadi as ca

        self.ca = ca
        model = problem.model
        forces = model.forces
        sc = forces.scales
        self.radius = sc.radius_m
        self.speed = sc.speed_m_s
        self.ballistic = forces.ballistic_factor
        aero = forces.aero
        if not isinstance(aero, PolynomialAero):
            raise ValueError("the NLP covers polynomial aerodynamics only")
        self.cl_c = aero.cl_coefficients
        self.cd_c = aero.cd_coefficients
        self.cd_of_cl = aero.cd_argument == "cl"
        self.omega = float(model.omega)
        self.thruster = model.thruster
        self.nx, self.nu = model.n_states, model.n_controls
        atmosphere = forces.atmosphere
        self._log_rho_table: Any = None
        self._exponential: tuple[float, float] | None = None
        if isinstance(atmosphere, US76Atmosphere):
            grid = _us76_grid()
            rho, _ = US76Atmosphere().density(grid)
            knots, coefficients = pchip_bspline(grid, np.log(rho))
            self._log_rho_table = ca.Function.bspline(
                "log_rho_us76",
                [knots.tolist()],
                coefficients.tolist(),
                [3],
                1,
                {"lookup_mode": ["binary"]},
            )
        elif isinstance(atmosphere, ExponentialAtmosphere):
            self._exponential = (math.log(atmosphere.rho0), atmosphere.scale_height_m)
        else:
            raise ValueError("the NLP covers the exponential and US76 atmospheres only")

    def log_density(self, h_m: Any) -> Any:
        """ln(rho / (kg/m^3)) at geometric altitude ``h_m`` (m)."""
        if self._exponential is not None:
            log_rho0, scale_height = self._exponential
            return log_rho0 - h_m / scale_height
        return self._log_rho_table(h_m)

    def _aero(self, x: Any, u: Any, log_rho: Any) -> tuple[Any, Any, Any, Any]:
        """Aerodynamic lift and drag (in m0 g0), ln(rho) and alpha in degrees; ``log_rho`` None:
        from the atmosphere at x's altitude."""
        alpha_deg = u[0] * (180.0 / math.pi)
        if log_rho is None:
            log_rho = self.log_density((x[0] - 1.0) * self.radius)
        cl = _poly(self.cl_c, alpha_deg)
        cd = _poly(self.cd_c, cl if self.cd_of_cl else alpha_deg)
        q = self.ballistic * self.ca.exp(log_rho) * x[3] * x[3]
        return q * cl, q * cd, log_rho, alpha_deg

    def _mass_thrust(self, x: Any, u: Any) -> tuple[Any, Any]:
        thr = self.thruster
        if thr is None:
            return 1.0, 0.0
        return x[6], x[7] if thr.lagged else u[2]

    def rates(self, x: Any, u: Any, log_rho: Any = None) -> Any:
        """dx/dt of one state column ``x`` under one control column ``u`` (``log_rho``: ln of
        the density at x's altitude, when it is given)."""
        ca = self.ca
        r, phi, v, gam, psi = x[0], x[2], x[3], x[4], x[5]
        alpha, sigma = u[0], u[1]
        lift_a, drag_a, _, _ = self._aero(x, u, log_rho)
        m, thrust = self._mass_thrust(x, u)
        lift = (lift_a + thrust * ca.sin(alpha)) / m
        drag = (drag_a - thrust * ca.cos(alpha)) / m
        sg, cg, sp, cp, sf, cf = (
            ca.sin(gam),
            ca.cos(gam),
            ca.sin(psi),
            ca.cos(psi),
            ca.sin(phi),
            ca.cos(phi),
        )
        w = self.omega
        dv = -drag - sg / (r * r)
        dgam = lift * ca.cos(sigma) / v + (v - 1.0 / (r * v)) * cg / r
        dpsi = lift * ca.sin(sigma) / (v * cg) + v * cg * sp * ca.tan(phi) / r
        if w != 0.0:
            dv = dv + w * w * r * cf * (sg * cf - cg * sf * cp)
            dgam = dgam + 2.0 * w * cf * sp + w * w * r * cf * (cg * cf + sg * cp * sf) / v
            dpsi = (
                dpsi - 2.0 * w * (ca.tan(gam) * cp * cf - sf) + w * w * r * sp * sf * cf / (v * cg)
            )
        out = [v * sg, v * cg * sp / (r * cf), v * cg * cp / r, dv, dgam, dpsi]
        thr = self.thruster
        if thr is not None:
            out.append(-thr.flow * thrust)
            if thr.lag_rate is not None:
                out.append(thr.lag_rate * (u[2] - x[7]))
        return ca.vertcat(*out)

    def path(self, x: Any, u: Any, limits: PathLimits, log_rho: Any = None) -> dict[str, Any]:
        """Heat rate (W/m^2), dynamic pressure (Pa) and aerodynamic load factor (g0) at one point,
        the ones ``limits`` bound."""
        ca = self.ca
        lift_a, drag_a, log_rho, alpha_deg = self._aero(x, u, log_rho)
        m, _ = self._mass_thrust(x, u)
        v_si = x[3] * self.speed
        out: dict[str, Any] = {}
        heat = limits.heat
        if limits.heat_max_W_m2 is not None and heat is not None:
            qa = _poly(heat.alpha_polynomial, alpha_deg) if heat.alpha_polynomial else 1.0
            out["heat_rate"] = (
                heat.k_q
                * ca.exp(heat.density_exponent * log_rho)
                * v_si**heat.velocity_exponent
                * qa
            )
        if limits.dynamic_pressure_max_Pa is not None:
            out["dynamic_pressure"] = 0.5 * ca.exp(log_rho) * v_si * v_si
        if limits.load_factor_max_g is not None:
            out["load_factor"] = ca.sqrt(lift_a * lift_a + drag_a * drag_a) / m
        return out

    def functions(self, limits: PathLimits) -> tuple[Any, Any]:
        """The rates and the path ratios (value / limit, <= 1) as CasADi functions of (x, u).

        Everything but the density table is one SX function of (x, u, ln rho), which CasADi
        evaluates and differentiates far faster than the same graph in MX; the table (a
        B-spline, MX only) feeds it."""
        ca = self.ca
        xs = ca.SX.sym("x", self.nx)
        us = ca.SX.sym("u", self.nu)
        lr = ca.SX.sym("log_rho")
        caps = {
            "heat_rate": limits.heat_max_W_m2,
            "dynamic_pressure": limits.dynamic_pressure_max_Pa,
            "load_factor": limits.load_factor_max_g,
        }
        path = self.path(xs, us, limits, lr)  # only the quantities with a limit
        ratios = [value / float(caps[name] or 1.0) for name, value in path.items()]
        f_sx = ca.Function("rates_sx", [xs, us, lr], [self.rates(xs, us, lr)])
        g_sx = ca.Function(
            "path_sx", [xs, us, lr], [ca.vertcat(*ratios) if ratios else ca.SX(0, 1)]
        )
        x = ca.MX.sym("x", self.nx)
        u = ca.MX.sym("u", self.nu)
        log_rho = self.log_density((x[0] - 1.0) * self.radius)
        f = ca.Function("rates", [x, u], [f_sx(x, u, log_rho)])
        g = ca.Function("path", [x, u], [g_sx(x, u, log_rho)])
        return f, g


@dataclass
class SkipSolution:
    """What one IPOPT solve gave: its status, iterations, solve wall time (IPOPT only, the NLP
    already built), the propellant burnt (kg) and each phase's duration (s)."""

    status: str
    success: bool
    iterations: int
    solve_s: float
    propellant_kg: float
    durations_s: list[float] = field(default_factory=list)
    end_states: list[dict[str, float]] = field(default_factory=list)


@dataclass
class _Phase:
    X: Any
    Xm: Any
    U: Any
    Um: Any
    tau: Any
    n: int


class SkipNlp:
    """The Hermite–Simpson NLP of a phased problem document, ``intervals[p]`` uniform intervals
    in phase p, built once."""

    def __init__(
        self,
        document: dict[str, Any] | ProblemDocument,
        intervals: Sequence[int] = DEFAULT_INTERVALS,
        max_iter: int = 3000,
        tol: float = 1e-8,
    ) -> None:
        import casadi as ca

        self.ca = ca
        doc = (
            document
            if isinstance(document, ProblemDocument)
            else ProblemDocument.model_validate(document)
        )
        self.problem = pb = build_phased_problem(doc)
        if len(intervals) != len(pb.phases):
            raise ValueError(f"{len(intervals)} interval counts for {len(pb.phases)} phases")
        names = [t.name for t in pb.base.objective]
        if names != ["min_propellant"] or pb.model.thruster is None:
            raise ValueError("the NLP covers the objective min_propellant of a powered vehicle")
        self.dyn = CasadiPowered(pb)
        self.intervals = [int(n) for n in intervals]
        self.max_iter = max_iter
        self.tol = tol
        self._build()
        self._guess()

    def _build(self) -> None:
        ca, pb, dyn = self.ca, self.problem, self.dyn
        opti = ca.Opti()
        nx, nu = dyn.nx, dyn.nu
        thr = pb.model.thruster
        assert thr is not None
        x_lo = np.full(nx, -np.inf)
        x_hi = np.full(nx, np.inf)
        x_lo[0], x_hi[0] = 1.0, 1.0 + R_MAX_ALTITUDE_M / dyn.radius
        x_lo[3] = SPEED_MIN
        x_lo[6] = thr.dry_mass if thr.dry_mass is not None else 1e-3
        x_hi[6] = 1.0
        if thr.lagged:
            x_lo[7], x_hi[7] = 0.0, thr.max_thrust
        phases: list[_Phase] = []
        for p, (ph, n) in enumerate(zip(pb.phases, self.intervals, strict=True)):
            X = opti.variable(nx, n + 1)
            Xm = opti.variable(nx, n)
            U = opti.variable(nu, n + 1)
            Um = opti.variable(nu, n)
            tau = opti.variable()
            f, g = dyn.functions(ph.limits)
            F = f.map(n + 1)(X, U)
            Fm = f.map(n)(Xm, Um)
            h = tau / n
            opti.subject_to(Xm == 0.5 * (X[:, :-1] + X[:, 1:]) + h / 8.0 * (F[:, :-1] - F[:, 1:]))
            opti.subject_to(X[:, 1:] - X[:, :-1] == h / 6.0 * (F[:, :-1] + 4.0 * Fm + F[:, 1:]))
            if g.numel_out(0):
                opti.subject_to(ca.vec(g.map(n + 1)(X, U)) <= 1.0)
                opti.subject_to(ca.vec(g.map(n)(Xm, Um)) <= 1.0)
            for cols in (X, Xm):
                for i in range(nx):
                    if np.isfinite(x_lo[i]) or np.isfinite(x_hi[i]):
                        opti.subject_to(opti.bounded(x_lo[i], cols[i, :], x_hi[i]))
            u_lo = [ph.alpha_range[0], ph.bank_range[0], 0.0]
            u_hi = [ph.alpha_range[1], ph.bank_range[1], ph.thrust_max]
            for cols in (U, Um):
                for i in range(nu):
                    opti.subject_to(opti.bounded(u_lo[i], cols[i, :], u_hi[i]))
            opti.subject_to(opti.bounded(ph.duration_min, tau, ph.duration_max))
            if p == 0:
                opti.subject_to(X[:, 0] == pb.x0)
            else:
                opti.subject_to(X[:, 0] == phases[-1].X[:, -1])
            for i, name in enumerate(TIME_STATE_NAMES):
                target = ph.end[name]
                if target.kind in ("fixed", "soft"):
                    opti.subject_to(X[i, n] == target.value)
                elif target.kind == "range":
                    opti.subject_to(opti.bounded(target.lo, X[i, n], target.hi))
            phases.append(_Phase(X, Xm, U, Um, tau, n))
        self.final_mass = phases[-1].X[6, -1]
        opti.minimize(1.0 - self.final_mass)
        opti.solver(
            "ipopt",
            {"print_time": False, "record_time": True, "detect_simple_bounds": True},
            {
                "print_level": 0,
                "sb": "yes",
                "max_iter": self.max_iter,
                "tol": self.tol,
                "linear_solver": "mumps",
            },
        )
        self.opti = opti
        self.phases = phases

    def _guess(self) -> None:
        """One RK4 propagation of every phase with constant controls (module docstring)."""
        pb, dyn = self.problem, self.dyn
        f, _ = dyn.functions(PathLimits())
        thr = pb.model.thruster
        assert thr is not None
        dry = thr.dry_mass if thr.dry_mass is not None else 1e-3
        dt = GUESS_STEP_S / pb.base.scales.time_s
        x = np.asarray(pb.x0, dtype=float)
        for ph, v in zip(pb.phases, self.phases, strict=True):
            u = np.array(
                [
                    np.clip(math.radians(GUESS_ALPHA_DEG), *ph.alpha_range),
                    np.clip(math.radians(GUESS_BANK_DEG), *ph.bank_range),
                    ph.thrust_max,
                ]
            )
            end = ph.end["altitude_m"]
            r_end = end.value if end.kind in ("fixed", "soft") else None
            above = r_end is not None and x[0] > r_end
            xs, t = [x], 0.0
            while t < ph.duration_max:
                k1 = f(x, u).full().ravel()
                k2 = f(x + 0.5 * dt * k1, u).full().ravel()
                k3 = f(x + 0.5 * dt * k2, u).full().ravel()
                k4 = f(x + dt * k3, u).full().ravel()
                x = x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
                x[6] = max(x[6], dry)
                t += dt
                xs.append(x)
                crossed = r_end is not None and (x[0] > r_end) != above
                if x[0] < 1.0 or (crossed and t >= ph.duration_min):
                    break
            tau = min(max(t, ph.duration_min), ph.duration_max)
            arr = np.array(xs)
            times = np.linspace(0.0, t, arr.shape[0])
            nodes = np.linspace(0.0, tau, v.n + 1)
            mids = 0.5 * (nodes[:-1] + nodes[1:])
            self.opti.set_initial(v.X, _resample(times, arr, nodes))
            self.opti.set_initial(v.Xm, _resample(times, arr, mids))
            self.opti.set_initial(v.U, np.tile(u[:, None], (1, v.n + 1)))
            self.opti.set_initial(v.Um, np.tile(u[:, None], (1, v.n)))
            self.opti.set_initial(v.tau, tau)
            x = _resample(times, arr, np.array([tau]))[:, 0]

    def solve(self) -> SkipSolution:
        """Solve from the built guess; the time is IPOPT's solve alone."""
        opti = self.opti
        start = time.perf_counter()
        try:
            sol: Any = opti.solve()
            stats = sol.stats()
            value = sol.value
        except RuntimeError:
            stats = opti.stats()
            value = opti.debug.value
        elapsed = time.perf_counter() - start
        solve_s = float(stats.get("t_wall_total", elapsed))
        pb = self.problem
        sc = pb.base.scales
        final_mass = float(value(self.final_mass))
        durations = [float(value(v.tau)) * sc.time_s for v in self.phases]
        ends = []
        for v in self.phases:
            end = np.asarray(value(v.X[:, -1])).ravel()
            ends.append(
                {
                    "altitude_m": (end[0] - 1.0) * sc.radius_m,
                    "longitude_deg": math.degrees(end[1]),
                    "latitude_deg": math.degrees(end[2]),
                    "velocity_m_s": end[3] * sc.speed_m_s,
                    "flight_path_angle_deg": math.degrees(end[4]),
                    "heading_deg": math.degrees(end[5]),
                    "mass_kg": end[6] * pb.mass_kg,
                }
            )
        return SkipSolution(
            status=str(stats.get("return_status")),
            success=bool(stats.get("success", False)),
            iterations=int(stats.get("iter_count", -1)),
            solve_s=solve_s,
            propellant_kg=(1.0 - final_mass) * pb.mass_kg,
            durations_s=durations,
            end_states=ends,
        )


def _resample(times: np.ndarray, rows: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The columns of ``rows`` (one row per time) interpolated at ``at``: (columns, len(at))."""
    return np.array([np.interp(at, times, rows[:, i]) for i in range(rows.shape[1])])


def scenario_document(name: str = SCENARIO) -> dict[str, Any]:
    """A copy of a built-in scenario's problem document."""
    return copy.deepcopy(get_scenario(name).problem)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--intervals", type=int, nargs="+", default=list(DEFAULT_INTERVALS))
    parser.add_argument("--scenario", default=SCENARIO)
    args = parser.parse_args()
    start = time.perf_counter()
    nlp = SkipNlp(scenario_document(args.scenario), args.intervals)
    build_s = time.perf_counter() - start
    solution = nlp.solve()
    off = 100.0 * (solution.propellant_kg / REFERENCE_PROPELLANT_KG - 1.0)
    print(
        f"intervals per phase: {' + '.join(str(n) for n in args.intervals)} (build {build_s:.2f} s)"
    )
    print(f"IPOPT: {solution.status}, {solution.iterations} iterations, {solution.solve_s:.2f} s")
    print(
        f"propellant {solution.propellant_kg:.3f} kg ({off:+.4f} % against "
        f"{REFERENCE_PROPELLANT_KG} kg); phases "
        + ", ".join(f"{d:.2f} s" for d in solution.durations_s)
    )


if __name__ == "__main__":
    main()
